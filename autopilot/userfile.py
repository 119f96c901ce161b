"""Reading a file a user hands in: one clear message instead of a traceback.

Every text file the commands read (configuration, vessel parameters,
missions, trial CSVs, steady-state tables) goes through :func:`read_text`:
UTF-8, with a leading byte-order mark accepted (Excel's "CSV UTF-8" and some
Windows editors write one). A directory, a missing or unreadable file, a
binary file, UTF-16 text and other encodings (Latin-1 from an old editor) are
refused with a :class:`~autopilot.schema.ConfigError` that names the file and
says what it is instead; the CLI turns that into one line and exit code 2.
"""

from __future__ import annotations

import codecs
import contextlib
import errno
import re
from pathlib import Path

from autopilot.schema import ConfigError

__all__ = ["read_text", "check_file", "check_text_head", "parse_yaml", "output_dir", "output_file", "PLOT_SUFFIXES",
           "number_cell", "known_names", "unique_header", "too_many_fields", "MISSING_CELLS", "units_row_refusal", "degrees_minutes", "coordinate_hint", "other_file_kind"]

PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")  # what the figures can be saved as

_BINARY_SNIFF = 8192


def check_file(path: str | Path, *, what: str = "file") -> Path:
    """``path`` as a Path if it names a readable regular file; ConfigError otherwise."""
    import stat

    p = Path(path)
    try:
        if p.is_dir():
            raise ConfigError(f"{p}: is a directory, not a {what}")
        with p.open("rb"):
            pass
        if not stat.S_ISREG(p.stat().st_mode):
            # a pipe is read once: the look at its first bytes (is it text? a log?) used up what the reading then
            # missed: a review of <(zcat log.gz) lost its first 39 cycles and its mission_start, and said exit 0
            raise ConfigError(f"{p}: a pipe or a device, not a file (read once, its start would be lost); save it "
                              f"to a file first")
    except ConfigError:
        raise
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read ({exc.strerror or exc})") from None
    return p


def check_text_head(p: Path, head: bytes, *, what: str = "file", binary_ok: bool = False) -> None:
    """ConfigError naming ``p`` when its first bytes are UTF-16 text or binary data (not a UTF-8 ``what``).
    ``binary_ok``: stray binary bytes are let through (a serial capture's line noise), UTF-16 and gzip are not."""
    if head.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        excel = " (in Excel: 'CSV UTF-8')" if p.suffix.lower() == ".csv" else ""
        raise ConfigError(f"{p}: UTF-16 text; save the {what} as UTF-8{excel}")
    if head.startswith(b"\x1f\x8b"):  # gzip's magic: "binary data" did not say what to do
        raise ConfigError(f"{p}: gzip-compressed; decompress it first (gunzip {p.name})")
    sniff = head[:_BINARY_SNIFF]
    if b"\x00" in sniff:
        # UTF-16 without a byte-order mark: every other byte of its ASCII text is a zero (it was "binary data")
        odd, even = sniff[1::2], sniff[0::2]
        if len(sniff) >= 8 and odd.count(0) >= 0.9 * len(odd) and even.count(0) <= 0.1 * len(even):
            raise ConfigError(f"{p}: UTF-16 text (without a byte-order mark); save the {what} as UTF-8")
        if not binary_ok:
            raise ConfigError(f"{p}: binary data, not a text {what}")


def read_text(path: str | Path, *, what: str = "file", spreadsheet: bool = False) -> str:
    """The UTF-8 text of a user's file, a leading BOM removed; ConfigError naming the file otherwise.

    ``spreadsheet`` (a CSV): text that is not UTF-8 is read as Windows-1252, what Excel's plain "CSV" writes
    on a Western-European Windows (a label or a comment with an o-umlaut or a degree sign was refused), and
    UTF-16 with its byte-order mark is read as such: Excel's "Unicode Text" (tab-separated) writes it."""
    p = check_file(path, what=what)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if spreadsheet and data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        with contextlib.suppress(UnicodeDecodeError):
            text = data.decode("utf-16")
            if "\x00" not in text:
                return text.lstrip("\ufeff")
    check_text_head(p, data, what=what)
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8):]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        if spreadsheet:
            with contextlib.suppress(UnicodeDecodeError):
                return data.decode("cp1252")
        byte = data[exc.start]
        raise ConfigError(
            f"{p}: not UTF-8 text (byte 0x{byte:02X} at offset {exc.start}; Latin-1 or another encoding?): "
            f"save the {what} as UTF-8"
        ) from None


def csv_rows(text: str) -> list[list[str]]:
    """The rows of a CSV text, stripped cells; blank lines and ``#`` comment lines left out.

    The delimiter is the header line's: a comma, or the semicolon or tab that spreadsheets
    write in locales where the comma is the decimal separator; there a number's decimal comma is
    read as a point ("10,5" is 10.5: with a semicolon between the cells it cannot be two cells).
    """
    import csv
    import io

    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        return []
    declared = re.fullmatch(r"\s*\"?sep=(.)\"?[,;\t]*\s*", lines[0])  # Excel's "sep=;" line names the delimiter
    if declared:
        lines = lines[1:]
        if not lines:
            return []
    head = lines[0]
    delimiter = declared.group(1) if declared else "," if "," in head else ";" if ";" in head else "\t" if "\t" in head else ","
    rows = [[c.strip() for c in row] for row in csv.reader(io.StringIO("\n".join(lines)), delimiter=delimiter)]
    if delimiter != ",":
        rows = [[_point(c) for c in row] for row in rows]
    return rows


_DECIMAL_COMMA = re.compile(r"[-+]?\d*,\d+(?:[eE][-+]?\d+)?")


def _point(cell: str) -> str:
    """A number written with a decimal comma, with a point instead; any other cell as it is."""
    return cell.replace(",", ".") if _DECIMAL_COMMA.fullmatch(cell) else cell


def too_many_fields(row: list[str], width: int, k: int) -> str | None:
    """What is wrong with data row ``k`` when it has more non-empty fields than the header's ``width``, else None:
    "10,5,20,3" under two columns is decimal commas, read as 10 and 5 and used without a word."""
    if len(row) <= width or not any(c for c in row[width:]):
        return None
    return (f"data row {k} has {len(row)} fields under a header of {width} (decimal commas? save the CSV with a "
            f"point as the decimal separator)")


def units_row(row: list[str]) -> bool:
    """A first data row of words only, none a number (its units: s, m, deg, N; it was refused as "'s' is not a
    number"). A row with any number in it is data."""
    cells = [c for c in row if c.strip()]
    if not cells:
        return False
    for c in cells:
        if _DECIMAL_COMMA.fullmatch(c):  # a number, its comma quoted in a comma-separated file: data, not units
            return False
        try:
            float(c)
        except ValueError:
            continue
        return False
    return True


def known_names(header: list[str], known) -> list[str]:
    """The header with each cell that names a known column in other letter case (T_S, Heading_Deg) spelled as
    the column is: refused as "no t_s column (T_S, ...)" before (a new user's test)."""
    by_lower = {k.lower(): k for k in known}
    return [h if h in known else by_lower.get(h.strip().lower(), h) for h in header]


def unit_word(cell: str) -> str:
    """A units row's cell as a bare unit: "[m]", "(m)", " M " are "m"."""
    return re.sub(r"\s+", " ", cell.strip().strip("[]()").strip().lower())


# the ways a units row under a CSV header says each SI unit a column's name gives (unit_word's form; the first is
# the one said back): a north_m in ft or a sog_m_s in kn read as metres or m/s would fly, or fit, another boat
SECONDS = ("s", "sec", "secs", "second", "seconds")
METRES = ("m", "metre", "metres", "meter", "meters")
DEGREES = ("deg", "°", "degree", "degrees", "dd", "decimal degrees")
METRES_PER_SECOND = ("m/s", "m s-1", "ms-1", "m*s-1")
DEGREES_PER_SECOND = ("deg/s", "°/s", "deg s-1", "degrees/s")
RADIANS_PER_SECOND = ("rad/s", "rad s-1", "radians/s")
NEWTONS = ("n", "newton", "newtons")
PERCENT = ("%", "pct", "percent")


def unit_mismatch(units: list[str], header: list[str], allowed: dict[str, tuple[str, ...]]) -> tuple[str, str] | None:
    """(column, its cell as written) of the first column whose unit in a units row under ``header`` is not the one
    its name says (``allowed``: column -> its unit's words, the first the one to say back), or None (a unit left
    empty is no contradiction)."""
    for k, name in enumerate(header):
        said = unit_word(units[k]) if k < len(units) else ""
        if name in allowed and said and said not in allowed[name]:
            return name, units[k].strip()
    return None


def units_row_refusal(path, units: list[str], header: list[str], allowed: dict[str, tuple[str, ...]],
                      what: str) -> str | None:
    """Why a units row under ``header`` is refused (:func:`unit_mismatch`: a column whose unit is not the one its
    name says), naming the file and the column, or None; ``what``: the file's kind ("mission", "trial CSV")."""
    bad = unit_mismatch(units, header, allowed)
    if bad is None:
        return None
    name, unit = bad
    return (f"{path}: the units row under the header gives {name} in {unit!r}; the {what} reads {name} in "
            f"{allowed[name][0]} (convert the column, or correct the unit)")


MISSING_CELLS = frozenset({"", "nan", "NaN", "NAN", "NA", "N/A", "n/a", "null", "-", "#N/A", "#NV"})  # what tools write for "no value"


def number_cell(text: str, row: int, column: str, header=()) -> float:
    """A CSV cell: a finite number, or NaN for an empty or "no value" cell; anything else is refused naming the
    row and the column (it was read as empty, without a word: a thrust of inf, a decimal comma, a stray word).
    ``header``: the file's column names (a cell that is one of them is a second file's header)."""
    import math

    if text in MISSING_CELLS:
        return math.nan
    try:
        value = float(text)
    except ValueError:
        hint = ""
        # a sysid audit: two trial CSVs joined, header and all (the second's columns in another order, or opening
        # with Excel's byte order mark)
        if text.lstrip("\ufeff").strip().lower() in {h.strip().lower() for h in (column, *header)}:
            hint = " (the header again: two files joined into one? give each its own file)"
        elif _DECIMAL_COMMA.fullmatch(text):
            hint = " (a decimal comma: save the CSV with a point as the decimal separator)"
        elif re.fullmatch(r"\d{1,2}:\d{2}(:\d{2}([.,]\d+)?)?", text):
            hint = " (a clock time: give the time in seconds, such as seconds since the start; in Excel =(A2-$A$2)*86400)"
        raise ConfigError(f"data row {row}, {column}: {text!r} is not a number{hint}") from None
    if not math.isfinite(value):
        raise ConfigError(f"data row {row}, {column}: {text} is not a finite number (leave the cell empty if it has no value)")
    return value


def degrees_minutes(value: float, limit_deg: float) -> float | None:
    """``value`` read as NMEA's degrees and minutes (4807.038 = 48 deg 07.038 min, 01131.000 = 11 deg 31 min), in
    decimal degrees, when it is outside +-``limit_deg`` as a plain number but a valid angle that way (minutes below
    60); else None. A latitude copied from a GGA sentence or a receiver's display was refused only as "outside
    -90..90 deg" (a new-user audit)."""
    import math

    if not math.isfinite(value) or abs(value) <= limit_deg:
        return None
    whole_deg, minutes = divmod(abs(value), 100.0)
    if minutes >= 60.0 or whole_deg > limit_deg:
        return None
    deg = whole_deg + minutes / 60.0
    return math.copysign(deg, value) if deg <= limit_deg else None


_HEMISPHERE = re.compile(r"\s*([-+]?\d+(?:\.\d+)?)\s*([NSEWnsew])\s*")
_DEGREE_SIGN = re.compile(r"\s*([-+]?\d+(?:\.\d+)?)\s*°\s*(?:(\d+(?:\.\d+)?)\s*['′]?)?\s*([NSEWnsew])?\s*")


def coordinate_hint(text: str, limit_deg: float) -> str:
    """What to write instead of a latitude or longitude given with a hemisphere letter, a degree sign or in degrees
    and minutes ("4807.038N", "52°00.006'N"), as " (...)" to add to its refusal; "" when ``text`` is none of them."""
    text = str(text).strip()
    m = _DEGREE_SIGN.fullmatch(text)
    if m is not None:
        deg = abs(float(m.group(1))) + (float(m.group(2)) / 60.0 if m.group(2) else 0.0)
        negative = m.group(1).startswith("-") or (m.group(3) or "").upper() in ("S", "W")
    else:
        m = _HEMISPHERE.fullmatch(text)
        if m is None:
            return ""
        value = abs(float(m.group(1)))
        whole_deg, minutes = divmod(value, 100.0)
        # degrees and minutes as NMEA writes them (4807.038N, 00030.500E): four or more digits before the point
        ddmm = len(m.group(1).lstrip("+-").split(".")[0]) >= 4 and minutes < 60.0
        deg = whole_deg + minutes / 60.0 if ddmm else value
        negative = m.group(1).startswith("-") or m.group(2).upper() in ("S", "W")
    if deg > limit_deg:
        return " (write decimal degrees, negative for south and west)"
    return f" (write decimal degrees, negative for south and west: {text} is {-deg if negative else deg:.6f})"


def unique_header(header: list[str], wanted) -> None:
    """ConfigError when a column the reader uses appears twice (the last copy silently won)."""
    for name in wanted:
        at = [k + 1 for k, h in enumerate(header) if h == name]
        if len(at) > 1:
            raise ConfigError(f"column {name} appears {len(at)} times (columns {', '.join(map(str, at))}): keep one")


def parse_yaml(text: str):
    """The YAML document in ``text``, a mapping's duplicate key refused (yaml.YAMLError naming it and both lines).

    PyYAML keeps the last of two equal keys without a word: a configuration with ``rate_hz`` twice ran at
    the second value, a mission with two ``waypoints`` blocks flew only the second."""
    import yaml

    return yaml.load(text, Loader=_unique_key_loader())  # noqa: S506 - a SafeLoader subclass


def yaml_problem(exc) -> str:
    """One line for a YAML syntax error: where (line and column, from 1) and what, without PyYAML's
    multi-line excerpt of the text and its '<unicode string>' (a tab said as a tab: YAML indents with spaces).
    """
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None)
    if mark is None or not problem:
        return str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    text = f"line {mark.line + 1}, column {mark.column + 1}: {problem}"
    context, context_mark = getattr(exc, "context", None), getattr(exc, "context_mark", None)
    if context:
        text += f", {context}" + (f" from line {context_mark.line + 1}" if context_mark is not None
                                  and context_mark.line != mark.line else "")
    if "'\\t'" in problem:
        text += " (a tab: YAML indents with spaces only)"
    return text


_LOADER = None


def _unique_key_loader():
    global _LOADER
    if _LOADER is None:
        import yaml

        class DuplicateKeyError(yaml.YAMLError):
            pass

        class LeadingZeroError(yaml.YAMLError):
            pass

        class UniqueKeyLoader(yaml.SafeLoader):
            pass

        def mapping(loader, node, deep=False):
            loader.flatten_mapping(node)
            first_line: dict = {}
            for key_node, _ in node.value:
                key = loader.construct_object(key_node, deep=True)
                try:
                    if key in first_line:
                        raise DuplicateKeyError(f"{key}: duplicate key (lines {first_line[key] + 1} and "
                                                f"{key_node.start_mark.line + 1})")
                    first_line[key] = key_node.start_mark.line
                except TypeError:  # an unhashable key: the constructor says so itself
                    pass
            return loader.construct_mapping(node, deep=deep)

        UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, mapping)

        def integer(loader, node):
            # YAML 1.1 reads a leading zero as octal: `rate_hz: 010` ran at 8 Hz without a word (YAML 1.2 and
            # every user read ten). Refused, saying both; 0 itself is zero.
            text = str(node.value).replace("_", "")
            if re.fullmatch(r"[-+]?0[0-9]+", text):
                raise LeadingZeroError(f"line {node.start_mark.line + 1}, column {node.start_mark.column + 1}: "
                                        f"{node.value}: a leading zero makes it octal in YAML "
                                        f"({loader.construct_yaml_int(node)}); write {int(text, 10)}")
            return loader.construct_yaml_int(node)

        UniqueKeyLoader.add_constructor("tag:yaml.org,2002:int", integer)
        # YAML 1.1 wants a dot in a float: PyYAML reads ``1e9`` or ``5E-3`` as a string, so a spec's
        # ``runs: 1e4`` was refused as "not a number" while the user sees a number.  YAML 1.2 reads them as
        # floats; so do we (plain scalars only: a quoted "1e9" stays a string).
        UniqueKeyLoader.add_implicit_resolver(
            "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
            list("-+0123456789"))
        _LOADER = UniqueKeyLoader
    return _LOADER


def other_file_kind(path: str | Path) -> str | None:
    """What the YAML file at ``path`` is when it is one of the project's other files (a mission, a vessel parameter
    set, the daemon's configuration), by its top-level keys; None when it is none of them or cannot be read."""
    try:
        data = parse_yaml(read_text(path))
    except Exception:  # noqa: BLE001 - only a hint: the refusal itself stands whatever this finds
        return None
    if not isinstance(data, dict):
        return None
    if "waypoints" in data:
        return "a mission (it has waypoints)"
    if "mass_kg" in data:
        return "a vessel parameter set (it has mass_kg)"
    if {"serial", "failsafe", "rate_hz"} & set(data):
        return "a daemon configuration (it has " + next(k for k in ("serial", "failsafe", "rate_hz") if k in data) + ")"
    return None


NO_ROOM_ERRNOS = frozenset({errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EROFS})  # the disk, not the program


@contextlib.contextmanager
def writing(path: str | Path):
    """Name ``path`` in an OSError raised while writing it (a write that fails on a full disk says only
    'File too large' or 'No space left on device', not which file)."""
    try:
        yield
    except OSError as exc:
        if exc.filename is None:
            raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc
        raise


def output_dir(path: str | Path, *, what: str = "--out", files: tuple[str, ...] = (), summary_is_ours=None,
               command: str = "the command") -> Path:
    """``path`` created if need be and writable, checked before any work; ConfigError naming it otherwise
    (a file where the directory should be, no permission: the work would have been lost at the end). ``files``:
    names the command writes there; a directory by one of those names is refused too (it was an 'internal
    error: IsADirectoryError' after the whole fit). ``summary_is_ours(parsed summary.json) -> bool``: a
    summary.json there that another command wrote is refused (``autopilot sysid --out`` into a review's folder
    wrote over its summary and removed its report.html, a new user's test)."""
    import json
    import tempfile

    if not str(path).strip():  # Path("") is the working directory: a campaign's results landed there unasked
        raise ConfigError(f"{what}: empty; give a directory (. for this one)")
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise ConfigError(f"{what} {p}: is a file, not a directory")
    for name in files:
        if (p / name).is_dir():
            raise ConfigError(f"{what} {p}: {p / name} is a directory; the command writes a file of that name there")
    summary = p / "summary.json"
    if summary_is_ours is not None and summary.is_file():
        try:
            ours = summary_is_ours(json.loads(summary.read_text(encoding="utf-8")))
        except (OSError, UnicodeDecodeError, ValueError):
            ours = False
        if not ours:
            raise ConfigError(f"{what} {p}: holds a summary.json that {command} did not write (another command's "
                              f"results), which it would write over: give a directory of its own")
    try:
        p.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=p):
            pass
    except OSError as exc:
        raise ConfigError(f"{what} {p}: cannot write there ({exc.strerror or exc})") from None
    return p


def output_file(path: str | Path, *, what: str, suffixes: tuple[str, ...] | None = None) -> Path:
    """A file to be written at ``path``: its suffix one of ``suffixes`` (if given), its directory created and
    writable; ConfigError naming it otherwise."""
    p = Path(path)
    if suffixes is not None and p.suffix.lower() not in suffixes:
        raise ConfigError(f"{what} {p}: the name must end in {', '.join(suffixes)}")
    if p.is_dir():
        raise ConfigError(f"{what} {p}: is a directory; give a file name")
    output_dir(p.parent if str(p.parent) else ".", what=f"{what} {p}: its directory")
    return p
