"""The lab of drkfs-onnx (``pip install -e ./bench``, beside the library): the benchmark that
decides accuracy (``benchmark``, ``drkfs bench``), the nets' training and the selection that
makes the benchmark's sets validation (``training``, ``drkfs train``), judging reconstructions
(``judging``, ``drkfs choose-loss``), the studies (``studies``) and the scripts that run them
(``python bench/NAME.py``, importable as ``drkfs_lab.NAME``). No library module names it;
``drkfs`` loads its commands through an entry point."""
