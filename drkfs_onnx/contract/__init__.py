"""The torch-free contract both paths read: the frozen ``PipelineConfig`` (``config``), meshes
and their frames (``mesh``), the cameras (``cameras``), the render equations
(``render_equations``), the match rules (``match_rules``), the patch grid (``patch_grid``), the
shipped model files and manifest (``model_files``) and the command lines' shared options
(``cli_options``).

Imports numpy, trimesh and typer only: ``runtime/`` may import this and nothing else of the
package (a test holds both rules). Code that runs on numpy arrays and torch tensors alike takes
an ``ArrayOps`` (``array_ops``) for every step that is not arithmetic or indexing.
"""
