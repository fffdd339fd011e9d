"""The metric's two nets in torch: the PoI detector (``detector``) and HardNet (``hardnet``),
the patches cut between them (``patches``), their convolutions' precision (``precision``) and
the shipped weights they load (``weights``). ``export/`` turns them into the ONNX feature graph
the runtime runs."""
