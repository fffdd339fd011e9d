"""bench/record_tables: each record's tables are printed from the JSON it reports, so a figure
typed into a record, a stale table, an indented one or a record without a printer is named;
``write`` puts the printed tables in place."""

import json
import shutil

import pytest
from conftest import ROOT

from drkfs_lab import record_tables


@pytest.mark.parametrize("name", record_tables.records())
def test_every_table_of_the_record_is_printed_from_its_json(name):
    assert record_tables.differences(name) == []


def _copy(tmp_path, name: str):
    """A repository under tmp_path holding the committed results and record ``name``."""
    shutil.copytree(ROOT / "bench" / "results", tmp_path / "bench" / "results")
    (tmp_path / "bench" / "records").mkdir()
    record = tmp_path / "bench" / "records" / f"{name}.md"
    shutil.copy(ROOT / "bench" / "records" / f"{name}.md", record)
    return record


def test_a_figure_typed_into_a_record_is_named_and_write_prints_it_back(tmp_path):
    record = _copy(tmp_path, "real_levers")
    text = record.read_text()
    typed = text.replace("| 0.94 | 0.829 | 3.27 |", "| 0.94 | 0.839 | 3.27 |", 1)
    assert typed != text
    record.write_text(typed)
    (found,) = record_tables.differences("real_levers", tmp_path)
    assert "real_levers.md table 3" in found and "0.839" in found
    record_tables.write("real_levers", tmp_path)
    assert record.read_text() == text


def test_a_record_with_a_table_more_than_printed_is_refused(tmp_path):
    record = _copy(tmp_path, "real_levers")
    record.write_text(record.read_text() + "\n| a | b |\n|---|---|\n| 1 | 2 |\n")
    assert record_tables.differences("real_levers", tmp_path) == [
        "real_levers.md holds 24 tables, 23 are printed"
    ]
    with pytest.raises(ValueError, match="holds 24 tables, 23 are printed"):
        record_tables.write("real_levers", tmp_path)


def test_an_indented_table_is_held_without_its_indent_and_written_back_at_it(tmp_path):
    record = _copy(tmp_path, "real_levers")
    text = record.read_text()
    first = record_tables.tables_in(text)[0]
    indented = "  " + first.replace("\n", "\n  ")
    record.write_text(text.replace(first, indented))
    assert record_tables.differences("real_levers", tmp_path) == []
    typed = indented.replace(" 0.971 ", " 0.917 ", 1)
    record.write_text(text.replace(first, typed))
    (found,) = record_tables.differences("real_levers", tmp_path)
    assert "table 1" in found and "0.917" in found
    record_tables.write("real_levers", tmp_path)
    assert record.read_text() == text.replace(first, indented)


def test_a_record_needs_a_printer_and_there_are_records(tmp_path):
    _copy(tmp_path, "real_levers")
    (tmp_path / "bench" / "records" / "new_study.md").write_text("| a |\n|---|\n| 1 |\n")
    assert "new_study" in record_tables.records(tmp_path)
    with pytest.raises(ValueError, match="new_study.md has no printer"):
        record_tables.differences("new_study", tmp_path)
    with pytest.raises(FileNotFoundError, match="no records"):
        record_tables.records(tmp_path / "elsewhere")


def test_a_studys_runs_print_in_the_records_order_and_one_unlisted_is_refused(tmp_path):
    from drkfs_lab.record_tables import single_view

    study = tmp_path / single_view.STUDY
    study.mkdir(parents=True)
    for name in ("speed.json", "speed-540-steps.json"):  # the second sorts first by name
        (study / name).write_text(json.dumps({"name": name}))
    listed = ("speed.json", "speed-540-steps.json")
    printed = single_view.study_runs(lambda run: run["name"], listed, tmp_path)
    assert printed == "speed.json\n\nspeed-540-steps.json"
    (study / "speed-on-a-gpu.json").write_text("{}")
    with pytest.raises(ValueError, match="speed-on-a-gpu.json not in the record"):
        single_view.study_runs(str, listed, tmp_path)
