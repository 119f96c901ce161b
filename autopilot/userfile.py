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

__all__ = ["read_text", "check_file", "check_text_head", "parse_yaml", "output_dir", "output_file", "PLOT_SUFFIXES"]

PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")  # what the figures can be saved as

_BINARY_SNIFF = 8192


def check_file(path: str | Path, *, what: str = "file") -> Path:
    """``path`` as a Path if it names a readable regular file; ConfigError otherwise."""
    p = Path(path)
    try:
        if p.is_dir():
            raise ConfigError(f"{p}: is a directory, not a {what}")
        with p.open("rb"):
            pass
    except ConfigError:
        raise
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read ({exc.strerror or exc})") from None
    return p


def check_text_head(p: Path, head: bytes, *, what: str = "file") -> None:
    """ConfigError naming ``p`` when its first bytes are UTF-16 text or binary data (not a UTF-8 ``what``)."""
    if head.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        excel = " (in Excel: 'CSV UTF-8')" if p.suffix.lower() == ".csv" else ""
        raise ConfigError(f"{p}: UTF-16 text; save the {what} as UTF-8{excel}")
    if b"\x00" in head[:_BINARY_SNIFF]:
        raise ConfigError(f"{p}: binary data, not a text {what}")


def read_text(path: str | Path, *, what: str = "file") -> str:
    """The UTF-8 text of a user's file, a leading BOM removed; ConfigError naming the file otherwise."""
    p = check_file(path, what=what)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise ConfigError(f"{p}: cannot read ({exc.strerror or exc})") from None
    check_text_head(p, data, what=what)
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8):]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        byte = data[exc.start]
        raise ConfigError(
            f"{p}: not UTF-8 text (byte 0x{byte:02X} at offset {exc.start}; Latin-1 or another encoding?): "
            f"save the {what} as UTF-8"
        ) from None


def csv_rows(text: str) -> list[list[str]]:
    """The rows of a CSV text, stripped cells; blank lines and ``#`` comment lines left out.

    The delimiter is the header line's: a comma, or the semicolon or tab that spreadsheets
    write in locales where the comma is the decimal separator.
    """
    import csv
    import io

    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        return []
    head = lines[0]
    delimiter = "," if "," in head else ";" if ";" in head else "\t" if "\t" in head else ","
    return [[c.strip() for c in row] for row in csv.reader(io.StringIO("\n".join(lines)), delimiter=delimiter)]


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
        # YAML 1.1 wants a dot in a float: PyYAML reads ``1e9`` or ``5E-3`` as a string, so a spec's
        # ``runs: 1e4`` was refused as "not a number" while the user sees a number.  YAML 1.2 reads them as
        # floats; so do we (plain scalars only: a quoted "1e9" stays a string).
        UniqueKeyLoader.add_implicit_resolver(
            "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
            list("-+0123456789"))
        _LOADER = UniqueKeyLoader
    return _LOADER


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


def output_dir(path: str | Path, *, what: str = "--out") -> Path:
    """``path`` created if need be and writable, checked before any work; ConfigError naming it otherwise
    (a file where the directory should be, no permission: the work would have been lost at the end)."""
    import tempfile

    p = Path(path)
    if p.exists() and not p.is_dir():
        raise ConfigError(f"{what} {p}: is a file, not a directory")
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
