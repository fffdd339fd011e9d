"""The speed work (``python bench/single_view.py --speed``, studies.speed): every loss timed in
one run, a cheaper loss trained and judged on validation shapes beside the same loss at a full
step."""

import json

import pytest
import torch
from typer.testing import CliRunner

from drkfs_lab.single_view import app
from drkfs_lab.studies.shape_generator import ShapeGenerator
from drkfs_lab.studies.single_view import (
    BFLOAT16,
    CAMERA_GROUPS,
    CHEAPER,
    DRKFS_SHADED,
    QUICK,
    RECIPE,
    SOFTRAS,
    Shape,
    Terms,
    study_sets,
)
from drkfs_lab.studies.speed import FULL_STEP, TIMED, speed_markdown, summarise_speed
from drkfs_lab.studies.views import CHANNELS, IMAGE_SIZE


def test_each_cheaper_loss_is_set_against_the_same_loss_at_a_full_step():
    assert set(CAMERA_GROUPS.values()) == {2, 3}  # divisors of the stages' 12 and 6 cameras
    assert set(CHEAPER) == {*CAMERA_GROUPS, BFLOAT16}
    for name, full in FULL_STEP.items():
        assert full == (RECIPE if name.endswith(" + 3 x Chamfer-L2") else DRKFS_SHADED)
        assert name.startswith("DR-KFS (") and name in TIMED
    assert TIMED[0] == SOFTRAS  # the timings' baseline, in the same run


def test_each_cheaper_loss_is_built_as_its_name_says():
    """A third of the cameras: the loss's view_groups 3, its nets in float32; HardNet in
    bfloat16: every camera, every stage's nets at conv_precision 'bfloat16'."""
    shapes = study_sets(QUICK)[0][:1]
    faces = ShapeGenerator(CHANNELS, IMAGE_SIZE).faces
    terms = Terms(shapes, torch.zeros(1), faces, 0)
    built = {}
    for name in (DRKFS_SHADED, *CHEAPER):
        loss, _ = terms.prepare(name)
        built[name] = (loss.view_groups, {m.conv_precision for m in loss.metrics})
    assert built == {
        DRKFS_SHADED: (1, {"ieee"}),
        **{name: (groups, {"ieee"}) for name, groups in CAMERA_GROUPS.items()},
        BFLOAT16: (1, {"bfloat16"}),
    }


@pytest.mark.slow
def test_the_speed_run_times_every_loss_and_judges_a_grouped_loss_on_validation(tmp_path):
    out = tmp_path / "out"
    grouped = "DR-KFS (a third of the cameras a step)"
    args = ["--quick", "--speed", "--losses", grouped, "--seeds", "0", "--out", str(out)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    found = json.loads((out / "speed.json").read_text())
    assert list(found["seconds_per_step"]) == list(TIMED)
    assert all(seconds > 0 for seconds in found["seconds_per_step"].values())
    assert list(found["means"]["pooled"]) == [DRKFS_SHADED, grouped]
    tables = {int(key.split()[1]): table for key, table in found["tables"].items()}
    shapes = [Shape(n, n.split()[0], None, None) for n in tables[0]]
    again = summarise_speed(tables, shapes, found["losses"])
    assert again["means"] == found["means"] and again["shares"] == found["shares"]
    assert f"| {grouped} | {DRKFS_SHADED} |" in speed_markdown(found)
    refused = CliRunner().invoke(app, [*args[:3], "DR-KFS", *args[4:]])
    assert refused.exit_code == 2 and "not a cheaper loss" in refused.output
    # at equal cost: the grouped loss trained for more steps, beside the same networks
    longer = CliRunner().invoke(app, [*args, "--steps", "3"])
    assert longer.exit_code == 0, longer.output
    found = json.loads((out / "speed-3-steps.json").read_text())
    assert (found["steps"], found["grouped_steps"]) == (2, 3)
    assert "full step 2 steps, cheaper 3" in speed_markdown(found)
    assert (out / "networks-3-steps" / "seed0").is_dir()
