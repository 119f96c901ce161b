"""What the SC-30 sends, at which rate, and whether it fits the line (SPEC 10).

A real SC-30 is configured (by its display unit) with the sentences it
outputs and their rates; the simulated one takes the same choice. At 8N1 a
character takes 10 bits, so the line carries baud / 10 characters a second
(4800 baud: 480). Heading-type sentences at 10 Hz and position at 1 Hz do not
all fit at 4800 baud: docs/sc30.md lists what does, per baud rate.
"""

from __future__ import annotations

__all__ = ["SENTENCES", "TYPICAL_CHARS", "LINE_SHARE_MAX", "default_sentences", "line_load_cps", "check_sentences"]

SENTENCES = ("HDT", "THS", "PFEC_GPatt", "ROT", "GGA", "RMC", "GLL", "VTG", "ZDA")
# characters on the wire of each sentence as this device writes it, CR LF included (the longest
# usual values: ROT "-5500.0" deg/min when spinning, a four-digit GGA altitude); 10 bits a character at 8N1
TYPICAL_CHARS = {"HDT": 19, "THS": 19, "ROT": 22, "PFEC_GPatt": 32, "GGA": 72, "RMC": 72, "GLL": 52, "VTG": 40, "ZDA": 38}
LINE_SHARE_MAX = 0.95  # a line loaded beyond this delays every sentence behind the 1 Hz group


def default_sentences(baudrate: int) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(10 Hz sentences, 1 Hz sentences) that fit in the baud rate's ~baud/10 chars/s (see docs/sc30.md)."""
    if baudrate >= 19200:
        return ("HDT", "PFEC_GPatt", "ROT"), ("GGA", "RMC", "VTG", "ZDA")
    if baudrate >= 9600:  # VTG repeats RMC's speed and course, the daemon does not use ZDA
        return ("HDT", "PFEC_GPatt", "ROT"), ("GGA", "RMC")
    return ("HDT",), ("ROT", "GGA", "RMC", "VTG", "ZDA")


def line_load_cps(fast, slow, *, fast_hz: float = 10.0, slow_hz: float = 1.0) -> float:
    """Characters per second the sentence sets put on the line."""
    return fast_hz * sum(TYPICAL_CHARS[k] for k in fast) + slow_hz * sum(TYPICAL_CHARS[k] for k in slow)


def check_sentences(baudrate: int, fast, slow) -> None:
    """ValueError when the sets do not fit in the line (it carries baud / 10 characters a second)."""
    unknown = [k for k in (*fast, *slow) if k not in TYPICAL_CHARS]
    if unknown:
        raise ValueError(f"unknown sentence {unknown[0]!r} (known: {', '.join(SENTENCES)})")
    load, cap = line_load_cps(fast, slow), baudrate / 10.0
    if load > LINE_SHARE_MAX * cap:
        raise ValueError(
            f"{'+'.join(fast)} at 10 Hz and {'+'.join(slow)} at 1 Hz need ~{load:.0f} characters a second; "
            f"{baudrate} baud carries {cap:.0f} (at most {LINE_SHARE_MAX:.0%} of it usable): send fewer sentences "
            "or raise the baud rate"
        )




def render_table(bauds=(4800, 9600, 19200, 38400)) -> str:
    """The per-baud table of docs/sc30.md (Markdown)."""
    rows = ["| baud | characters/s on the line | 10 Hz | 1 Hz | load |", "|---|---|---|---|---|"]
    for b in bauds:
        fast, slow = default_sentences(b)
        load = line_load_cps(fast, slow)
        rows.append(f"| {b} | {b // 10} | {', '.join(fast)} | {', '.join(slow)} | {load:.0f} cps ({load / (b / 10):.0%}) |")
    return "\n".join(rows) + "\n"
