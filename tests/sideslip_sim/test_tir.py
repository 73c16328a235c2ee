"""The .tir reader: what it accepts, and that every refusal names file, line and key."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

try:
    from sideslip_sim import tir_file, tire
except ImportError:  # package not installed yet: use the source tree
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "sideslip_sim"))
    from sideslip_sim import tir_file, tire

SHIPPED = tire.DEFAULT_TIR


def _write(tmp_path: Path, text: str, name: str = "tyre.tir") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _shipped_with(tmp_path: Path, old: str, new: str) -> Path:
    text = SHIPPED.read_text()
    assert text.count(old) == 1, old
    return _write(tmp_path, text.replace(old, new))


def test_shipped_file_parses_with_its_sections_and_values():
    parsed = tir_file.parse_tir(SHIPPED)
    assert parsed.number("VERTICAL", "FNOMIN") == 4000.0
    assert parsed.number("LATERAL_COEFFICIENTS", "PKY1") == -14.95
    assert parsed.get("UNITS", "LENGTH") == "meter"
    assert parsed.get("MODEL", "TYRESIDE") == "LEFT"
    assert parsed.lines[("VERTICAL", "FNOMIN")] > 1


def test_shipped_file_round_trips_through_format_and_parse():
    parsed = tir_file.parse_tir(SHIPPED)
    again = tir_file.parse_tir_text(tir_file.format_tir(parsed), "round-trip")
    assert again.sections == parsed.sections
    assert tire.TireParams.from_tir_file(again).values == tire.TireParams.from_tir(SHIPPED).values


def test_comments_quotes_and_case_are_handled():
    text = (
        "! leading comment\n"
        "$------------------------------------------------ units\n"
        "[units]\n"
        "  length = 'meter'   $ trailing comment\n"
        "[Model]\n"
        "NOTE = 'costs $5 ! really'  ! the $ and ! inside quotes are text\n"
        "tyreside = LEFT\n"
        "LONGVL = 1.6670E+01$no space before the comment\n"
    )
    parsed = tir_file.parse_tir_text(text, "inline")
    assert parsed.get("UNITS", "LENGTH") == "meter"
    assert parsed.get("MODEL", "NOTE") == "costs $5 ! really"
    assert parsed.get("MODEL", "TYRESIDE") == "LEFT"
    assert parsed.number("model", "longvl") == 16.67


def test_table_sections_keep_their_rows():
    text = "[SHAPE]\n{radial width}\n 1.0 0.0\n 1.0 0.4\n 0.9 0.9\n"
    parsed = tir_file.parse_tir_text(text, "shape")
    assert parsed.tables["SHAPE"].columns == ("radial", "width")
    assert parsed.tables["SHAPE"].rows[-1] == (0.9, 0.9)


def test_malformed_line_is_refused_with_file_and_line(tmp_path):
    path = _write(tmp_path, "[VERTICAL]\nFNOMIN = 4000\nthis is not a key value line\n")
    with pytest.raises(tir_file.TirError, match=r"tyre file .*tyre\.tir, line 3: malformed line"):
        tir_file.parse_tir(path)


def test_key_before_any_section_is_refused(tmp_path):
    path = _write(tmp_path, "FNOMIN = 4000\n[VERTICAL]\n")
    with pytest.raises(tir_file.TirError, match=r"line 1: FNOMIN appears before any \[SECTION\]"):
        tir_file.parse_tir(path)


def test_duplicate_key_is_refused_naming_both_lines(tmp_path):
    path = _write(tmp_path, "[LATERAL_COEFFICIENTS]\nPKY1 = -14.95\n\nPKY1 = -15.0\n")
    with pytest.raises(tir_file.TirError) as info:
        tir_file.parse_tir(path)
    message = str(info.value)
    assert "line 4" in message and "first set on line 2" in message
    assert "[LATERAL_COEFFICIENTS] PKY1 duplicated" in message
    assert info.value.key == "PKY1" and info.value.line == 4


def test_unterminated_quote_is_refused(tmp_path):
    path = _write(tmp_path, "[UNITS]\nLENGTH = 'meter\n")
    with pytest.raises(tir_file.TirError, match=r"line 2: \[UNITS\] LENGTH: unterminated"):
        tir_file.parse_tir(path)


def test_unreadable_file_is_refused_naming_it(tmp_path):
    missing = tmp_path / "nope.tir"
    with pytest.raises(tir_file.TirError, match=r"tyre file .*nope\.tir: cannot be read"):
        tir_file.parse_tir(missing)


def test_non_numeric_value_is_refused_where_a_number_is_needed(tmp_path):
    path = _shipped_with(
        tmp_path,
        "PKY1                     = -14.95",
        "PKY1                     = 'stiff'",
    )
    with pytest.raises(tir_file.TirError) as info:
        tire.TireParams.from_tir(path)
    assert "[LATERAL_COEFFICIENTS] PKY1 = 'stiff' is not a number" in str(info.value)
    assert f"line {info.value.line}:" in str(info.value)
    assert str(path) in str(info.value)


def test_missing_required_key_is_named(tmp_path):
    lines = SHIPPED.read_text().splitlines(keepends=True)
    path = _write(tmp_path, "".join(ln for ln in lines if not ln.startswith("PKY1 ")))
    with pytest.raises(tir_file.TirError) as info:
        tire.TireParams.from_tir(path)
    assert str(info.value) == f"tyre file {path}: [LATERAL_COEFFICIENTS] PKY1 missing"
    assert info.value.key == "PKY1"


def test_non_si_units_are_refused(tmp_path):
    path = _shipped_with(tmp_path, "LENGTH                   = 'meter'", "LENGTH = 'mm'")
    with pytest.raises(tir_file.TirError, match=r"\[UNITS\] LENGTH = 'mm' not supported"):
        tire.TireParams.from_tir(path)


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        ("FNOMIN                   = 4000.0", "FNOMIN = -4000.0", r"\[VERTICAL\] FNOMIN .* > 0"),
        ("PCY1                     = 1.193", "PCY1 = 2.5", r"PCY1 = 2.5 must be in \(0, 2\]"),
        ("PDX1                     = 1.210", "PDX1 = nan", r"PDX1 = nan must be a finite"),
    ],
)
def test_out_of_range_values_are_refused_with_the_key(tmp_path, old, new, expected):
    with pytest.raises(tir_file.TirError, match=expected):
        tire.TireParams.from_tir(_shipped_with(tmp_path, old, new))
