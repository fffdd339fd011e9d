"""What may import what, folder by folder: the library's torch-free contract, the torch renderer
and nets on it, the metric and loss on top, the runtime on the contract alone; the lab (bench/,
installed as drkfs_lab) on the library, and never the library on the lab."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT

PACKAGE = ROOT / "drkfs_onnx"
LAB = ROOT / "bench"
# layer -> the layers its modules may import (besides their own). A folder of the library or of
# the lab is a layer; the library's own modules (the torch metric, its match and loss) are
# "metric", its command line "cli"; the lab's own modules (its scripts and command line) are
# "scripts". The training stage selects its nets on the benchmark's sets (which makes those sets
# validation for the nets), so training sits above the benchmark.
LIBRARY = {
    "contract": (),
    "render": ("contract",),
    "nets": ("contract",),
    "synthetic": ("contract",),
    "runtime": ("contract",),
    "metric": ("contract", "render", "nets"),
    "export": ("contract", "nets", "metric"),
    "models": (),
}
LIBRARY["cli"] = tuple(LIBRARY)  # the command line: every layer of the library
LAB_LAYERS = {
    "benchmark": (*LIBRARY,),
    "judging": (*LIBRARY, "benchmark"),
    "training": (*LIBRARY, "benchmark"),
    "studies": (*LIBRARY, "benchmark", "judging", "training"),
    "record_tables": (*LIBRARY, "benchmark", "judging", "training", "studies"),  # their records
}
LAB_LAYERS["scripts"] = (*LIBRARY, *LAB_LAYERS)  # the lab's scripts and command line: everything
ALLOWED = {**LIBRARY, **LAB_LAYERS}
FORBIDDEN = {"contract": ("torch", "onnx"), "runtime": ("torch", "onnx")}
OWN_MODULES = {"drkfs_onnx": ("metric", "cli"), "drkfs_lab": ("scripts",)}


def _root(layer: str) -> tuple[str, Path]:
    """The package name and folder of a layer."""
    return ("drkfs_lab", LAB) if layer in LAB_LAYERS else ("drkfs_onnx", PACKAGE)


def _layer(name: str) -> str:
    """The layer of a module of the library or the lab, by its dotted name."""
    package, folder = (
        ("drkfs_lab", LAB) if name.startswith("drkfs_lab") else ("drkfs_onnx", PACKAGE)
    )
    part = name.split(".")[1] if "." in name else ""
    if part and (folder / part).is_dir() and (folder / part / "__init__.py").is_file():
        return part
    if package == "drkfs_lab":
        return "scripts"
    return "cli" if part == "cli" else "metric"


def _layer_modules(layer: str) -> list[Path]:
    package, folder = _root(layer)
    if layer in OWN_MODULES[package]:
        own = sorted(folder.glob("*.py"))  # the package's __init__ among them
        return (
            own
            if package == "drkfs_lab"
            else [p for p in own if (p.stem == "cli") == (layer == "cli")]
        )
    return sorted((folder / layer).glob("*.py"))


def every_module() -> list[Path]:
    """Every module of the library and the lab: rglob does not follow the package's links to
    export/ and runtime/, so those folders are walked where they are."""
    folders = (PACKAGE, ROOT / "export", ROOT / "runtime", LAB)
    return sorted(path for folder in folders for path in folder.rglob("*.py"))


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


def test_every_folder_of_the_library_and_the_lab_is_a_layer():
    for package, folder in (("drkfs_onnx", PACKAGE), ("drkfs_lab", LAB)):
        layers = LIBRARY if package == "drkfs_onnx" else LAB_LAYERS
        folders = {p.name for p in folder.iterdir() if (p / "__init__.py").is_file()}
        assert folders == set(layers) - set(OWN_MODULES[package]), package


@pytest.mark.parametrize("layer", sorted(ALLOWED))
def test_each_layer_imports_only_the_layers_below_it(layer):
    allowed = {layer, *ALLOWED[layer]}
    package, _ = _root(layer)
    for path in _layer_modules(layer):
        own = layer in OWN_MODULES[package]
        for name in _imports(path, package if own else f"{package}.{layer}"):
            top = name.split(".")[0]
            if top in ("drkfs_onnx", "drkfs_lab") and name != top:
                assert _layer(name) in allowed, f"{path.relative_to(ROOT)} imports {name}"
            assert top not in FORBIDDEN.get(layer, ()), f"{layer}/{path.name} imports {name}"
            if layer in LIBRARY:
                assert top != "drkfs_lab", f"{path.relative_to(ROOT)} imports the lab's {name}"


def test_no_module_takes_a_private_name_from_another():
    for path in every_module():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module != "__future__":
                private = [a.name for a in node.names if a.name.startswith("_")]
                assert not private, f"{path.relative_to(ROOT)} imports {private} from {node.module}"


# the base install's runtime and contract import none of the extras' libraries; a module that
# is an extra's own (explain's picture: the plot extra) names it in its docstring's opening
EXTRAS_LIBRARIES = ("torch", "onnx", "matplotlib", "scipy", "ray")
EXTRA_MODULES = ("drkfs_onnx.runtime.explain_plot",)


def test_the_contract_and_the_runtime_import_on_a_base_install():
    """Every module of contract/ and runtime/ but an extra's own imports in a process where
    importing torch, onnx or another extra's library fails, and none of them is loaded after."""
    names = [
        f"drkfs_onnx.{folder}.{path.stem}" for folder in FORBIDDEN for path in _modules(folder)
    ]
    names = [name for name in names if name not in EXTRA_MODULES]
    code = (
        "import importlib, sys\n"
        f"for library in {EXTRAS_LIBRARIES!r}:\n"
        "    sys.modules[library] = None\n"
        f"for name in {names!r}:\n"
        "    importlib.import_module(name)\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in "
        f"{EXTRAS_LIBRARIES!r} and sys.modules[m] is not None))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"
    for name in EXTRA_MODULES:
        opening = (PACKAGE.parent / (name.replace(".", "/") + ".py")).read_text()[:200]
        assert '"drkfs-onnx[' in opening, f"{name} does not name its extra first"


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


# top-level test files that hold what crosses the modules: a device, the docs, a newcomer's
# first tries, this layout, the installs, the torch path's failures
CROSS_CUTTING = {
    "test_cuda",
    "test_docs",
    "test_first_tries",
    "test_layout",
    "test_packaging",
    "test_torch_edges",
}


def test_a_modules_tests_are_found_by_its_name():
    """tests/ mirrors the library's folders, and tests/lab/ the lab's: tests/X/test_NAME.py holds
    the module (or folder) X/NAME."""
    tests = ROOT / "tests"
    unmatched = []
    for path in sorted(tests.rglob("test_*.py")):
        parts = path.relative_to(tests).parts
        folder, within = (LAB, parts[1:-1]) if parts[0] == "lab" else (PACKAGE, parts[:-1])
        module = folder.joinpath(*within, path.stem.removeprefix("test_"))
        named = module.with_suffix(".py").is_file() or module.is_dir()
        if not named and path.stem not in CROSS_CUTTING:
            unmatched.append(str(path.relative_to(tests)))
    assert unmatched == [], f"test files that name no module where they lie: {unmatched}"
