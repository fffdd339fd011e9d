"""The package's folders say what may import what: the torch-free contract, the torch renderer and
nets on it, the metric and loss on top, the runtime on the contract alone."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "drkfs_onnx"
# folder -> the package's folders its modules may import (besides their own)
ALLOWED = {
    "contract": (),
    "render": ("contract",),
    "nets": ("contract",),
    "runtime": ("contract",),
}
FORBIDDEN = {"contract": ("torch", "onnx"), "runtime": ("torch", "onnx")}


def _imports(path: Path, package: str) -> set[str]:
    """The absolute names of the modules a file imports (relative imports resolved)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([node.module] if node.module else []))
            else:
                base = node.module
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names)
    return found


def _modules(folder: str) -> list[Path]:
    return sorted((PACKAGE / folder).glob("*.py"))


@pytest.mark.parametrize("folder", sorted(ALLOWED))
def test_each_folder_imports_only_the_folders_below_it(folder):
    allowed = {f"drkfs_onnx.{name}" for name in (folder, *ALLOWED[folder])}
    for path in _modules(folder):
        for name in _imports(path, f"drkfs_onnx.{folder}"):
            if name.split(".")[0] == "drkfs_onnx":  # the root too: it is the metric's layer
                top = ".".join(name.split(".")[:2])
                assert top in allowed, f"{folder}/{path.name} imports {name}"
            for library in FORBIDDEN.get(folder, ()):
                assert name.split(".")[0] != library, f"{folder}/{path.name} imports {name}"


def test_the_contract_and_the_runtime_import_where_torch_and_onnx_cannot():
    """Every module of contract/ and runtime/ imports in a process where importing torch or onnx
    fails, and none of the two is loaded after."""
    names = [
        f"drkfs_onnx.{folder}.{path.stem}" for folder in FORBIDDEN for path in _modules(folder)
    ]
    code = (
        "import importlib, sys\n"
        "sys.modules['torch'] = sys.modules['onnx'] = None\n"
        f"for name in {names!r}:\n"
        "    importlib.import_module(name)\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('torch', 'onnx')"
        " and sys.modules[m] is not None))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


def test_a_stage_is_found_by_its_folder_and_file_name():
    """The data flow's stages, each where docs/architecture.md's tree says."""
    stages = {
        "mesh in, frames": ["contract/mesh.py"],
        "cameras": ["contract/cameras.py"],
        "render": ["contract/render_equations.py", "render/renderer.py", "runtime/render.py"],
        "PoI maps": ["nets/detector.py"],
        "patches": ["nets/patches.py", "contract/patch_grid.py"],
        "descriptors": ["nets/hardnet.py"],
        "match": ["contract/match_rules.py", "match.py", "runtime/match.py"],
        "score": ["metric.py", "runtime/scorer.py"],
    }
    for stage, files in stages.items():
        for file in files:
            assert (PACKAGE / file).is_file(), f"{stage}: {file}"
