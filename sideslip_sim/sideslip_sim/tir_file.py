"""Reader for TNO / MF-Tyre ``.tir`` tyre property files.

A ``.tir`` file is plain text made of ``[SECTION]`` headers and ``KEY = value`` lines::

    $---------------------------------------------------------------- units
    [UNITS]
    LENGTH              = 'meter'        $ quoted strings use single quotes
    [LATERAL_COEFFICIENTS]
    PKY1                = -14.95         $Maximum value of stiffness Kfy/Fznom
    ! a line starting with '!' or '$' is a comment

Some sections (``[SHAPE]``, ``[DEFLECTION_LOAD_CURVE]``, ...) hold a table instead: a
``{column names}`` line followed by rows of numbers. Those rows are kept as tables.

Section and key names are matched case-insensitively and stored upper-case. Values that
read as numbers are stored as ``float``; everything else (quoted or bare words) as ``str``.
Which keys a model needs, and whether a value must be a number, is the model's business:
it asks with :meth:`TirFile.number`, which raises :class:`TirError` naming the file, the
section, the key and (where there is one) the line.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["TirError", "TirFile", "TirTable", "format_tir", "parse_tir", "parse_tir_text"]

_SECTION_RE = re.compile(r"^\[\s*([A-Za-z0-9_]+)\s*\]$")
_KEY_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


class TirError(ValueError):
    """A ``.tir`` file that cannot be read or lacks what the tyre model needs.

    Attributes name where the problem is, so callers (CLIs) can print one line.
    """

    def __init__(
        self,
        path: str,
        message: str,
        *,
        line: int | None = None,
        section: str | None = None,
        key: str | None = None,
    ) -> None:
        where = f"tyre file {path}" + (f", line {line}" if line is not None else "")
        super().__init__(f"{where}: {message}")
        self.path = path
        self.line = line
        self.section = section
        self.key = key


@dataclass(frozen=True)
class TirTable:
    """A numeric table inside a section: ``{col_a col_b}`` then rows of numbers."""

    columns: tuple[str, ...]
    rows: tuple[tuple[float, ...], ...]


@dataclass(frozen=True)
class TirFile:
    """Parsed contents of one ``.tir`` file.

    ``sections[SECTION][KEY]`` is a ``float`` or ``str``; ``lines[(SECTION, KEY)]`` is the
    1-based line the key was read from; ``tables[SECTION]`` holds table sections.
    """

    path: str
    sections: dict[str, dict[str, float | str]]
    lines: dict[tuple[str, str], int] = field(default_factory=dict)
    tables: dict[str, TirTable] = field(default_factory=dict)

    def has(self, section: str, key: str) -> bool:
        return key.upper() in self.sections.get(section.upper(), {})

    def get(self, section: str, key: str) -> float | str:
        """The raw value; :class:`TirError` ``"[SECTION] KEY missing"`` if absent."""
        section, key = section.upper(), key.upper()
        values = self.sections.get(section)
        if values is None or key not in values:
            raise TirError(self.path, f"[{section}] {key} missing", section=section, key=key)
        return values[key]

    def number(self, section: str, key: str) -> float:
        """The value as a float; :class:`TirError` if absent or not a number."""
        section, key = section.upper(), key.upper()
        value = self.get(section, key)
        if isinstance(value, str):
            raise TirError(
                self.path,
                f"[{section}] {key} = {value!r} is not a number",
                line=self.lines.get((section, key)),
                section=section,
                key=key,
            )
        return value

    def string(self, section: str, key: str) -> str:
        """The value as text (numbers are formatted back with ``repr``)."""
        value = self.get(section, key)
        return value if isinstance(value, str) else repr(value)


def parse_tir(path: str | Path) -> TirFile:
    """Read and parse the ``.tir`` file at ``path``.

    Raises :class:`TirError` for an unreadable file, a malformed line, a duplicate key in a
    section, or a key outside any section.
    """
    path_str = str(path)
    try:
        # errors="replace": vendor files carry Latin-1 bytes in comments; values are ASCII.
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise TirError(path_str, f"cannot be read ({exc.strerror})") from exc
    return parse_tir_text(text, path_str)


def parse_tir_text(text: str, path: str = "<string>") -> TirFile:
    """Parse ``.tir`` text; ``path`` only names the source in error messages."""
    sections: dict[str, dict[str, float | str]] = {}
    lines: dict[tuple[str, str], int] = {}
    table_columns: dict[str, tuple[str, ...]] = {}
    table_rows: dict[str, list[tuple[float, ...]]] = {}
    section: str | None = None

    for number, raw in enumerate(text.splitlines(), start=1):
        line = _strip_comment(raw).strip()
        if not line:
            continue

        header = _SECTION_RE.match(line)
        if header:
            section = header.group(1).upper()
            sections.setdefault(section, {})
            continue
        if line.startswith("["):
            raise TirError(path, f"malformed section header {raw.strip()!r}", line=number)

        if line.startswith("{"):
            if section is None or not line.endswith("}"):
                raise TirError(path, f"malformed table header {raw.strip()!r}", line=number)
            table_columns[section] = tuple(line[1:-1].split())
            table_rows[section] = []
            continue

        if "=" not in line:
            if section in table_columns:
                table_rows[section].append(_table_row(line, path, number, section))
                continue
            raise TirError(
                path, f"malformed line {raw.strip()!r} (expected KEY = value)", line=number
            )

        key_text, value_text = (part.strip() for part in line.split("=", 1))
        if not _KEY_RE.match(key_text):
            raise TirError(path, f"malformed key {key_text!r}", line=number)
        key = key_text.upper()
        if section is None:
            raise TirError(path, f"{key} appears before any [SECTION] header", line=number, key=key)
        if not value_text:
            raise TirError(
                path, f"[{section}] {key} has no value", line=number, section=section, key=key
            )
        if key in sections[section]:
            first = lines[(section, key)]
            raise TirError(
                path,
                f"[{section}] {key} duplicated (first set on line {first})",
                line=number,
                section=section,
                key=key,
            )
        sections[section][key] = _value(value_text, path, number, section, key)
        lines[(section, key)] = number

    tables = {
        name: TirTable(columns=table_columns[name], rows=tuple(table_rows[name]))
        for name in table_columns
    }
    return TirFile(path=path, sections=sections, lines=lines, tables=tables)


def format_tir(tir: TirFile) -> str:
    """Write ``tir`` back as ``.tir`` text (comments are not kept; values round-trip exactly).

    Strings are single-quoted; floats use ``repr`` so ``parse_tir_text(format_tir(t))``
    reproduces every value bit for bit.
    """
    out: list[str] = []
    for section, values in tir.sections.items():
        out.append(f"[{section}]")
        for key, value in values.items():
            text = f"'{value}'" if isinstance(value, str) else repr(value)
            out.append(f"{key:<24} = {text}")
        table = tir.tables.get(section)
        if table is not None:
            out.append("{" + " ".join(table.columns) + "}")
            out.extend(" ".join(repr(cell) for cell in row) for row in table.rows)
    return "\n".join(out) + "\n"


def _strip_comment(raw: str) -> str:
    """Drop a ``$`` or ``!`` comment, leaving those characters alone inside quotes."""
    in_quote = False
    for i, char in enumerate(raw):
        if char == "'":
            in_quote = not in_quote
        elif char in "$!" and not in_quote:
            return raw[:i]
    return raw


def _value(text: str, path: str, line: int, section: str, key: str) -> float | str:
    if text.startswith("'"):
        if len(text) < 2 or not text.endswith("'"):
            raise TirError(
                path,
                f"[{section}] {key}: unterminated quoted string {text!r}",
                line=line,
                section=section,
                key=key,
            )
        return text[1:-1]
    try:
        return float(text)
    except ValueError:
        return text  # a bare word such as LEFT; number() refuses it where a number is due


def _table_row(line: str, path: str, number: int, section: str) -> tuple[float, ...]:
    try:
        return tuple(float(cell) for cell in line.split())
    except ValueError as exc:
        raise TirError(
            path, f"[{section}] malformed table row {line!r}", line=number, section=section
        ) from exc
