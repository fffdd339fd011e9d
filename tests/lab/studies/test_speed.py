"""The speed work (``python bench/single_view.py --speed``, studies.speed): every loss timed in
one run, a cheaper loss trained and judged on validation shapes beside the same loss at a full
step."""

import json

import pytest
from typer.testing import CliRunner

from drkfs_lab.single_view import app
from drkfs_lab.studies.single_view import (
    BFLOAT16,
    CAMERA_GROUPS,
    CHEAPER,
    DRKFS_SHADED,
    RECIPE,
    SOFTRAS,
    Shape,
)
from drkfs_lab.studies.speed import FULL_STEP, TIMED, speed_markdown, summarise_speed


def test_each_cheaper_loss_is_set_against_the_same_loss_at_a_full_step():
    assert set(CAMERA_GROUPS.values()) == {2, 3}  # divisors of the stages' 12 and 6 cameras
    assert set(CHEAPER) == {*CAMERA_GROUPS, BFLOAT16}
    for name, full in FULL_STEP.items():
        assert full == (RECIPE if name.endswith(" + 3 x Chamfer-L2") else DRKFS_SHADED)
        assert name.startswith("DR-KFS (") and name in TIMED
    assert TIMED[0] == SOFTRAS  # the timings' baseline, in the same run


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
