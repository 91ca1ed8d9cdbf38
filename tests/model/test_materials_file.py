"""A user's materials file (model.materials_file): its rows add to the shipped table and replace
a shipped row of the same name, and every fault is refused naming the file, line, material and
column.  The constants are tests.materials_values' TEST VALUES, not any real alloy's."""

from __future__ import annotations

from pathlib import Path

import pytest

from model.materials import law_for, material, materials, user_table
from model.materials_file import NASGRO_COLUMNS, MaterialsFileError
from model.nasgro import NasgroTerms
from tests.materials_values import HEADER, TEST_2024, TEST_A, TEST_B, write_materials


def test_a_user_row_with_nasgro_terms_loads_and_is_selected_by_name(tmp_path: Path) -> None:
    path = write_materials(tmp_path / "ours.csv", TEST_A, TEST_B)
    table = materials(path)
    assert {"2024-T3", "7075-T6", "TEST-NASGRO-A", "TEST-NASGRO-B"} <= set(table)
    row = material("TEST-NASGRO-A", path)
    assert (row.c, row.m, row.gamma, row.k_ic_mpa_sqrt_m) == (6.7e-11, 3.8, 1.0, 60.0)
    assert row.nasgro == NasgroTerms(3.0, 60.0, 0.5, 1.0, 2.0, 0.3, 1.5, 0.1)
    assert (row.citation, row.note, row.file) == ("test values", "not a real alloy", str(path))
    law = law_for("TEST-NASGRO-B", None, path)
    assert (law.c, law.m, law.nasgro) == (9.0e-11, 3.5, material("TEST-NASGRO-B", path).nasgro)
    assert "TEST-NASGRO-A" not in materials()  # only where the file is named
    with pytest.raises(ValueError, match="unknown material 'TEST-NASGRO-A'"):
        material("TEST-NASGRO-A")


def test_a_user_row_named_as_a_shipped_one_replaces_it_whole(tmp_path: Path) -> None:
    path = write_materials(tmp_path / "ours.csv", TEST_2024)
    shipped, ours = material("2024-T3"), material("2024-T3", path)
    assert (ours.c, ours.m, ours.gamma, ours.source) == (2.0e-11, 3.3, 0.7, "test values")
    assert ours.nasgro is not None and shipped.nasgro is None
    assert shipped.source == "dowling-2013"  # the shipped table itself is untouched
    assert material("7075-T6", path) == material("7075-T6")


def test_the_file_is_read_once_per_process_like_any_setting(tmp_path: Path) -> None:
    path = write_materials(tmp_path / "ours.csv", TEST_A)
    assert set(user_table(path)) == {"TEST-NASGRO-A"}
    write_materials(path, TEST_A, TEST_B)  # takes effect at the next start
    assert set(user_table(path)) == {"TEST-NASGRO-A"}


def test_a_row_without_nasgro_columns_and_without_a_note_is_a_walker_row(tmp_path: Path) -> None:
    path = tmp_path / "walker.csv"
    path.write_text(
        "\ufeffname,c_m_per_cycle,m,gamma,k_ic_mpa_sqrt_m,source\n"
        'TEST-W, 1e-11 ,3.0,0.5,30,"lab, 2026"\n'
    )
    row = user_table(path)["TEST-W"]
    assert (row.c, row.gamma, row.nasgro, row.citation) == (1e-11, 0.5, None, "lab, 2026")


def test_a_row_may_give_its_plane_stress_toughness_and_yield_strength(tmp_path: Path) -> None:
    path = tmp_path / "strength.csv"
    head = "name,c_m_per_cycle,m,gamma,k_ic_mpa_sqrt_m,source,k_c_mpa_sqrt_m,yield_strength_mpa\n"
    path.write_text(head + "TEST-S,1e-11,3.0,0.5,30,lab,95,330\nTEST-T,1e-11,3.0,0.5,30,lab,,\n")
    rows = user_table(path)
    assert (rows["TEST-S"].k_c_mpa_sqrt_m, rows["TEST-S"].yield_strength_mpa) == (95.0, 330.0)
    assert (rows["TEST-T"].k_c_mpa_sqrt_m, rows["TEST-T"].yield_strength_mpa) == (None, None)
    assert material("2024-T3").yield_strength_mpa is None  # no cited value shipped
    bad = tmp_path / "bad.csv"
    bad.write_text(head + "TEST-S,1e-11,3.0,0.5,30,lab,95,-3\n")
    with pytest.raises(MaterialsFileError, match="column 'yield_strength_mpa': must be > 0"):
        user_table(bad)


def _nasgro_row(**values: str) -> str:
    """TEST_A with some cells replaced (column name: cell)."""
    cells = dict(zip(HEADER.split(","), TEST_A.split(","), strict=True))
    return ",".join({**cells, **values}.values())


@pytest.mark.parametrize(
    ("rows", "message"),
    [
        (
            [_nasgro_row(m="abc")],
            "line 3, material 'TEST-NASGRO-A', column 'm': not a number: 'abc'",
        ),
        ([_nasgro_row(c_m_per_cycle="-1e-11")], "column 'c_m_per_cycle': must be > 0, got -1e-11"),
        ([_nasgro_row(c_m_per_cycle="0")], "column 'c_m_per_cycle': must be > 0"),
        ([_nasgro_row(gamma="1.2")], "column 'gamma': must be in [0, 1], got 1.2"),
        ([_nasgro_row(k_ic_mpa_sqrt_m="")], "column 'k_ic_mpa_sqrt_m': empty; a number is needed"),
        ([_nasgro_row(m="nan")], "column 'm': must be > 0, got nan"),
        ([_nasgro_row(nasgro_p="-0.5")], "column 'nasgro_p': must be >= 0, got -0.5"),
        ([_nasgro_row(nasgro_q="")], "column 'nasgro_q': empty, while other NASGRO columns"),
        (
            [_nasgro_row(nasgro_smax_on_flow_stress="1")],
            "column 'nasgro_smax_on_flow_stress': must be in [0, 1)",
        ),
        ([_nasgro_row(nasgro_dk0_mpa_sqrt_m="70")], "'nasgro_dk0_mpa_sqrt_m': the threshold"),
        ([_nasgro_row(nasgro_alpha="20")], "column 'nasgro_alpha': alpha must be > 0 with"),
        ([_nasgro_row(name="")], "line 3, column 'name': a material needs a name"),
        ([_nasgro_row(source="")], "column 'source': say where the constants come from"),
        ([TEST_A, TEST_A], "line 4, material 'TEST-NASGRO-A': the name is given twice"),
        ([TEST_A + ",1"], "line 3: 16 fields, the header has 15"),
        ([], "holds no material row"),
    ],
)
def test_a_bad_row_is_refused_naming_the_file_line_material_and_column(
    tmp_path: Path, rows: list[str], message: str
) -> None:
    path = write_materials(tmp_path / "bad.csv", *rows)
    with pytest.raises(MaterialsFileError, match=r"materials file .*bad\.csv: ") as refused:
        user_table(path)
    assert message in str(refused.value)
    assert "\n" not in str(refused.value)


@pytest.mark.parametrize(
    ("header", "message"),
    [
        ("name,c_m_per_cycle,m,k_ic_mpa_sqrt_m,source", "header: missing column 'gamma'"),
        (HEADER + ",density", "header: unknown column 'density'"),
        (HEADER.replace("nasgro_p,", ""), "header: missing column 'nasgro_p' (the NASGRO"),
        ("name,name,c_m_per_cycle,m,gamma,k_ic_mpa_sqrt_m,source", "column 'name' given twice"),
    ],
)
def test_a_bad_header_is_refused_naming_the_column(
    tmp_path: Path, header: str, message: str
) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(header + "\n")
    with pytest.raises(MaterialsFileError, match=r"bad\.csv: ") as refused:
        user_table(path)
    assert message in str(refused.value)


def test_an_unreadable_file_is_refused_naming_it(tmp_path: Path) -> None:
    with pytest.raises(MaterialsFileError, match=r"nowhere\.csv: cannot read"):
        user_table(tmp_path / "nowhere.csv")
    (tmp_path / "binary.csv").write_bytes(b"\xff\xfe\x00name")
    with pytest.raises(MaterialsFileError, match=r"binary\.csv: cannot read"):
        user_table(tmp_path / "binary.csv")
    (tmp_path / "empty.csv").write_text("# only a comment\n")
    with pytest.raises(MaterialsFileError, match=r"empty\.csv: no header line"):
        user_table(tmp_path / "empty.csv")
    assert len(NASGRO_COLUMNS) == 8
