"""The pairs CSV's rules: paths from the CSV's folder, extra columns and blank rows reported,
no pairs an error."""

from pathlib import Path

import pytest

from drkfs_onnx.runtime.pairs_file import read_pairs


def _csv(folder: Path, text: str) -> Path:
    (folder / "a.obj").write_text("")
    (folder / "b.obj").write_text("")
    path = folder / "pairs.csv"
    path.write_text(text)
    return path


def test_relative_paths_are_read_from_the_csvs_folder_and_absolute_ones_kept(tmp_path):
    pairs = _csv(tmp_path, f"mesh_a,mesh_b\na.obj,b.obj\n{tmp_path / 'a.obj'},sub/c.obj\n")
    assert read_pairs(pairs).pairs == [
        (str(tmp_path / "a.obj"), str(tmp_path / "b.obj")),
        (str(tmp_path / "a.obj"), str(tmp_path / "sub" / "c.obj")),
    ]
    # without a header the first row must be two files, found from the CSV's folder too
    assert read_pairs(_csv(tmp_path, "a.obj,b.obj\n")).pairs == [
        (str(tmp_path / "a.obj"), str(tmp_path / "b.obj"))
    ]


def test_extra_columns_are_named_and_blank_rows_reported_by_line(tmp_path):
    pairs = _csv(tmp_path, "id,mesh_b,mesh_a,\n1,b.obj,a.obj,\n,,,\n\n2,b.obj,a.obj,x\n")
    read = read_pairs(pairs)
    assert read.pairs == [(str(tmp_path / "a.obj"), str(tmp_path / "b.obj"))] * 2
    assert read.warnings == [
        f"{pairs}: blank rows skipped (lines 3, 4)",
        f"{pairs}: columns ignored: id, column 4",
    ]
    wide = read_pairs(_csv(tmp_path, "a.obj,b.obj\na.obj,b.obj,0.5\n"))
    assert wide.warnings == [f"{pairs}: only the first two columns are read (more on line 2)"]


def test_a_row_with_one_path_stays_a_row_that_fails_on_its_own(tmp_path):
    read = read_pairs(_csv(tmp_path, "mesh_a,mesh_b\na.obj\na.obj,b.obj\n"))
    assert read.pairs[0] == (str(tmp_path / "a.obj"), "") and len(read.pairs) == 2


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "no pairs (the file is empty)"),
        ("\n,\n", "no pairs (the file is empty)"),
        ("mesh_a,mesh_b\n", "no pairs below the header mesh_a,mesh_b"),
        ("pred,gt\na.obj,b.obj\n", "the first row pred,gt is neither the header mesh_a,mesh_b"),
    ],
)
def test_a_file_with_no_pairs_is_an_error_naming_it(tmp_path, text, message):
    pairs = _csv(tmp_path, text)
    with pytest.raises(ValueError, match="no pairs|first row") as error:
        read_pairs(pairs)
    assert str(error.value).startswith(f"{pairs}: {message}")


def test_a_file_that_is_not_utf8_text_is_refused_naming_it(tmp_path):
    pairs = tmp_path / "big.ply"
    pairs.write_bytes(b"ply\n\x96")
    with pytest.raises(ValueError, match=r"big\.ply: not a CSV of mesh pairs"):
        read_pairs(pairs)


def test_a_spreadsheets_byte_order_mark_is_no_part_of_the_header(tmp_path):
    pairs = _csv(tmp_path, "")
    pairs.write_bytes("\ufeffmesh_a,mesh_b\na.obj,b.obj\n".encode())
    read = read_pairs(pairs)
    assert read.pairs == [(str(tmp_path / "a.obj"), str(tmp_path / "b.obj"))]
    assert read.warnings == []


def test_a_rows_fields_beyond_the_header_are_named_by_line(tmp_path):
    pairs = _csv(tmp_path, "mesh_a,mesh_b\na.obj,b.obj\na.obj,b.obj,0.5\na.obj,b.obj,\n")
    read = read_pairs(pairs)
    assert len(read.pairs) == 3
    assert read.warnings == [f"{pairs}: fields beyond the header's 2 columns ignored (line 3)"]
