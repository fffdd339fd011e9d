"""What a reader and a fresh clone meet: the README's quick starts, docs a reader can follow, the
real meshes in the repository, and a test run that says what it leaves out."""

import re
import subprocess
import sys

import pytest
import tomllib
from conftest import ROOT

from drkfs_lab.benchmark import sets
from drkfs_onnx.synthetic.examples import write_examples

QUICK_STARTS = ("Score your two meshes", "Run a server", "Train a network")
RECORD_HEADINGS = ["Question", "Change", "Command", "Result", "Decision", "Metric version"]


def _sections(text: str) -> dict[str, list[str]]:
    found, name = {}, None
    for line in text.splitlines():
        if line.startswith("## "):
            name = line[3:].strip()
            found[name] = []
        elif name is not None:
            found[name].append(line)
    return found


def test_the_readme_opens_with_the_two_commands_and_has_a_short_quick_start_per_reader():
    text = (ROOT / "README.md").read_text()
    first = re.search(r"```bash\n(.*?)```", text, re.S).group(1)
    assert "drkfs-score batch examples/pairs.csv" in first
    installs = 'pip install torch==2.13.0 && pip install -e ".[torch,dev]" -e ./bench'
    test_command = f"{installs} && python -m pytest -q"
    assert test_command in first and test_command in (ROOT / ".ci" / "run").read_text()
    sections = _sections(text)
    for name in QUICK_STARTS:  # a quick start per reader, each under 30 lines
        lines = [line for line in sections[name] if line.strip()]
        assert len(lines) < 30, (name, len(lines))


def test_the_readme_table_of_examples_is_what_its_first_command_writes(tmp_path):
    """Each example's DR-KFS score in the README's first table, to the digits it shows, is the
    score ``drkfs-score batch examples/pairs.csv`` writes."""
    import csv

    from typer.testing import CliRunner

    from drkfs_onnx.runtime.cli import app

    out = tmp_path / "scores.csv"
    result = CliRunner().invoke(
        app, ["batch", str(ROOT / "examples" / "pairs.csv"), "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    scores = {row["mesh_a"]: float(row["score"]) for row in csv.DictReader(out.open())}
    rows = re.findall(
        r"^\| (\S+\.obj) \| [^|]+ \| ([0-9.]+) \|", (ROOT / "README.md").read_text(), re.M
    )
    assert sorted(name for name, _ in rows) == sorted(scores)
    for name, shown in rows:
        digits = len(shown.partition(".")[2])
        assert abs(scores[name] - float(shown)) <= 0.5 * 10**-digits, (name, shown, scores[name])


def test_the_docs_name_no_issue_and_no_command_that_no_longer_exists():
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        text = path.read_text()
        assert not re.search(r"\bissues? \d+|done-means", text, re.I), path.name
        assert "drkfs fit" not in text and "../shared/meshes" not in text, path.name


def test_every_real_mesh_is_in_the_repository_with_its_origin_and_terms():
    assert sets.CHECKOUT_MESHES == ROOT / "meshes"
    readme = (ROOT / "meshes" / "README.md").read_text()
    for name in sets.SHARED_MESHES:
        assert sets.real_mesh(name).is_file(), name
        (row,) = [line for line in readme.splitlines() if line.startswith(f"| {name}.obj |")]
        assert len(row.split("|")) == 7 and row.split("|")[-2].strip(), name  # its terms


def test_a_folder_without_the_real_meshes_is_named_with_where_they_come_from(tmp_path):
    code = "from drkfs_lab.benchmark.sets import real_mesh; real_mesh('cow')"
    env = {"DRKFS_MESHES": str(tmp_path), "PATH": ""}
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert f"{tmp_path / 'cow.obj'}: real mesh cow.obj not found" in result.stderr
    assert "--meshes DIR or DRKFS_MESHES" in result.stderr


def test_the_default_run_leaves_out_only_the_slow_studies_and_ci_runs_them():
    options = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]
    assert "-m 'not slow'" in options["addopts"]
    ci = (ROOT / ".ci" / "run").read_text()
    assert "python -m pytest -q -m slow" in ci and "python bench/check_results.py" in ci


def test_the_usage_pages_batches_example_runs_as_written_and_its_forms_agree(tmp_path, monkeypatch):
    text = (ROOT / "docs" / "usage.md").read_text()
    code = re.search(r"<!-- batches example -->\s*```python\n(.*?)```", text, re.S).group(1)
    namespace: dict = {}
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "docs/usage.md", "exec"), namespace)
    metric, gt = namespace["metric"], (namespace["gt_verts"], namespace["gt_faces"])
    ragged = metric([namespace["v0"], namespace["v1"]], [namespace["f0"], namespace["f1"]], *gt)
    assert float(metric(namespace["packed"], None, *gt)) == float(ragged) > 0


def test_the_reference_pages_are_short_and_the_studies_live_in_the_lab():
    # a user reads the README and docs/; how each default was chosen is the lab's
    # (bench/records), listed in its index
    readme = (ROOT / "README.md").read_text().splitlines()
    pages = sum(len(p.read_text().splitlines()) for p in (ROOT / "docs").glob("*.md"))
    assert len(readme) <= 200 and len(readme) + pages <= 1500, (len(readme), pages)
    records = ROOT / "bench" / "records"
    index = (records / "README.md").read_text()
    for record in records.glob("*.md"):
        assert record.name == "README.md" or f"]({record.name})" in index, record.name


def test_every_study_in_the_lab_has_the_six_headings_in_order():
    # one section a study in each bench/records file, each with the same headings, once each
    for record in sorted((ROOT / "bench" / "records").glob("*.md")):
        text = record.read_text()
        sections = _sections(text)
        titles = [line for line in text.splitlines() if line.startswith("## ")]
        assert len(sections) == len(titles), (record.name, "a title twice")
        for name, lines in sections.items():
            found = [m.group(1) for m in (re.match(r"- \*\*(.+?)\.\*\*", x) for x in lines) if m]
            assert found == RECORD_HEADINGS, (record.name, name, found)


def _python_blocks() -> list[tuple[str, str]]:
    """(where, code) of every Python block in the README and docs/ that has no test of its own
    (a block under an ``<!-- ... example -->`` marker has one)."""
    blocks = []
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        text = page.read_text()
        for found in re.finditer(r"(<!-- [^>]* example -->\s*)?```python\n(.*?)```", text, re.S):
            if not found.group(1):
                line = text[: found.start()].count("\n") + 1
                blocks.append((f"{page.relative_to(ROOT)}:{line}", found.group(2)))
    return blocks


@pytest.mark.parametrize("where", ["checkout", "elsewhere"])
def test_every_python_block_in_the_docs_runs_as_written(where, tmp_path, monkeypatch):
    # in a checkout's root, and in another folder where `drkfs examples` wrote the examples
    folder = ROOT if where == "checkout" else tmp_path
    if where == "elsewhere":
        write_examples(tmp_path / "examples")
    before = set(folder.iterdir())
    monkeypatch.chdir(folder)
    try:
        for name, code in _python_blocks():
            exec(compile(code, name, "exec"), {})
    finally:
        for made in set(folder.iterdir()) - before:  # what a block wrote (gt.npz)
            made.unlink()
