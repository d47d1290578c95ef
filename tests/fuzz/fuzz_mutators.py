"""Seeded, replayable mutations of input files for the CLI fuzz campaign.

A case is ``reader:source:seed:mutation+mutation``: which reader, which seed file, the integer
seed of the random choices inside the mutations, and the mutations applied in order. The same
case string always produces the same bytes (``random.Random(seed)``), so a failure found by the
test or by ``benchmarks/bench_fuzz.py`` replays with ``bench_fuzz.py --replay CASE``.

Content mutations take and return bytes; ``deleted`` and ``folder`` replace the file itself (it
disappears, or a folder of the same name stands in its place).
"""

from __future__ import annotations

import random
import re
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

Mutation = Callable[[bytes, random.Random], bytes]

#: Values written over numbers by ``special_value``.
SPECIAL_VALUES: tuple[bytes, ...] = (
    b"NaN", b"nan", b"-nan", b"inf", b"-inf", b"Infinity", b"-Infinity", b"1e30", b"-1e30",
    b"1e308", b"1e-320", b"0", b"-0", b"", b"+", b"1e", b"0x1F", b"1,5", b"99999999999999999999",
)
_NUMBER = re.compile(rb"(?<![\w.])[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?(?![\w.])")
_YAML_KEY = re.compile(rb"^(\s*)(-\s+)?([^\s#:'\"\[\]{}][^:#]*?):(\s.*|)$")
_XML_ELEMENT = re.compile(rb"^\s*<[A-Za-z_]")
_DELIMITERS = (b"\t", b",", b";", b" ")


def _lines(data: bytes) -> list[bytes]:
    return data.splitlines(keepends=True)


def _pick_line(n: int, rng: random.Random) -> int:
    """A line index; half the time among the first 40 lines, where headers and keys live."""
    if rng.random() < 0.5:
        return rng.randrange(min(n, 40))
    return rng.randrange(n)


def _ending(line: bytes) -> bytes:
    body = line.rstrip(b"\r\n")
    return line[len(body):]


def truncate(data: bytes, rng: random.Random) -> bytes:
    """Cut the file at a random byte (a copy interrupted, a disk full)."""
    return data[: rng.randrange(len(data))] if data else data


def byte_flip(data: bytes, rng: random.Random) -> bytes:
    """Flip one bit in 1-8 random bytes."""
    if not data:
        return data
    out = bytearray(data)
    for _ in range(rng.randint(1, 8)):
        i = rng.randrange(len(out))
        out[i] ^= 1 << rng.randrange(8)
    return bytes(out)


def delete_line(data: bytes, rng: random.Random) -> bytes:
    """Drop one line (often a header line)."""
    lines = _lines(data)
    if lines:
        del lines[_pick_line(len(lines), rng)]
    return b"".join(lines)


def duplicate_line(data: bytes, rng: random.Random) -> bytes:
    """Repeat one line right after itself."""
    lines = _lines(data)
    if lines:
        i = _pick_line(len(lines), rng)
        line = lines[i] if _ending(lines[i]) else lines[i] + b"\n"
        lines.insert(i + 1, line)
        lines[i] = line
    return b"".join(lines)


def swap_lines(data: bytes, rng: random.Random) -> bytes:
    """Exchange two lines (out-of-order samples, a header below data)."""
    lines = _lines(data)
    if len(lines) >= 2:
        i = _pick_line(len(lines), rng)
        j = rng.randrange(len(lines)) if rng.random() < 0.5 else min(i + 1, len(lines) - 1)
        a, b = lines[i], lines[j]
        ea, eb = _ending(a), _ending(b)
        lines[i] = b.rstrip(b"\r\n") + (ea or eb)
        lines[j] = a.rstrip(b"\r\n") + (eb or ea)
    return b"".join(lines)


def _delimiter(lines: list[bytes]) -> bytes:
    """The delimiter of the table: the most frequent of tab, comma, semicolon, space."""
    sample = b"".join(line for line in lines[:60] if not line.lstrip().startswith(b"//"))
    return max(_DELIMITERS, key=sample.count)


def _map_columns(data: bytes, rng: random.Random,
                 edit: Callable[[list[bytes], int, int], list[bytes]]) -> bytes:
    lines = _lines(data)
    if not lines:
        return data
    delim = _delimiter(lines)
    widths = [len(line.rstrip(b"\r\n").split(delim)) for line in lines]
    width = max(widths)
    if width < 2:
        return data
    i, j = rng.randrange(width), rng.randrange(width)
    out = []
    for line in lines:
        fields = line.rstrip(b"\r\n").split(delim)
        if len(fields) > max(i, j):
            fields = edit(fields, i, j)
        out.append(delim.join(fields) + _ending(line))
    return b"".join(out)


def delete_column(data: bytes, rng: random.Random) -> bytes:
    """Drop one delimited column from every row that has it."""
    return _map_columns(data, rng, lambda f, i, j: f[:i] + f[i + 1:])


def duplicate_column(data: bytes, rng: random.Random) -> bytes:
    """Repeat one delimited column (a duplicate header name and its values)."""
    return _map_columns(data, rng, lambda f, i, j: f[: i + 1] + [f[i]] + f[i + 1:])


def swap_columns(data: bytes, rng: random.Random) -> bytes:
    """Exchange two delimited columns in every row that has both."""
    def edit(f: list[bytes], i: int, j: int) -> list[bytes]:
        f = list(f)
        f[i], f[j] = f[j], f[i]
        return f
    return _map_columns(data, rng, edit)


def special_value(data: bytes, rng: random.Random) -> bytes:
    """Write NaN, inf, 1e30, empty or malformed numbers over 1-5 numbers (or a whole column)."""
    spans = [m.span() for m in _NUMBER.finditer(data)]
    if not spans:
        return data
    value = rng.choice(SPECIAL_VALUES)
    if rng.random() < 0.25:  # a run of consecutive numbers: a column stuck at one value
        start = rng.randrange(len(spans))
        chosen = spans[start: start + rng.randint(5, 200)]
    else:
        chosen = sorted(rng.sample(spans, min(len(spans), rng.randint(1, 5))))
    out, last = [], 0
    for a, b in chosen:
        out += [data[last:a], value]
        last = b
    out.append(data[last:])
    return b"".join(out)


def crlf(data: bytes, rng: random.Random) -> bytes:
    """Windows line endings (or, one time in four, old Mac lone CRs)."""
    unix = data.replace(b"\r\n", b"\n")
    return unix.replace(b"\n", b"\r" if rng.random() < 0.25 else b"\r\n")


def _text(data: bytes) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def utf16(data: bytes, rng: random.Random) -> bytes:
    """The same text saved as UTF-16 (with BOM, or big-endian without one)."""
    return _text(data).encode("utf-16" if rng.random() < 0.7 else "utf-16-be")


def bom(data: bytes, rng: random.Random) -> bytes:
    """A UTF-8 byte-order mark in front (as Windows editors write)."""
    return b"\xef\xbb\xbf" + data


def latin1(data: bytes, rng: random.Random) -> bytes:
    """Non-ASCII text saved as Latin-1 (not UTF-8) in one line, or the whole file re-encoded."""
    lines = _lines(data)
    words = ("Gerät", "température °C", "µs", "Capteur_é", "niño", "Ø")
    word = rng.choice(words).encode("latin-1")
    if not lines:
        return word
    i = _pick_line(len(lines), rng)
    line = lines[i]
    body = line.rstrip(b"\r\n")
    k = rng.randrange(len(body) + 1)
    lines[i] = body[:k] + word + body[k:] + _ending(line)
    return b"".join(lines)


def junk(data: bytes, rng: random.Random) -> bytes:
    """A line of garbage inserted: binary bytes with NUL, random text, or one very long line."""
    lines = _lines(data)
    kind = rng.randrange(5)
    if kind == 0:
        piece = bytes(rng.randrange(256) for _ in range(rng.randint(1, 64))) + b"\n"
    elif kind == 1:
        piece = "".join(rng.choice("abc XYZ019,;\t:-.[]{}&*!|>'\"#") for _ in range(40)).encode()
        piece += b"\n"
    elif kind == 2:
        piece = b"1," * 20000 + b"\n"
    elif kind == 3:
        piece = b"\x00" * rng.randint(1, 512)
    else:
        piece = b"<<<<<<< HEAD\n=======\n>>>>>>> branch\n"
    i = rng.randrange(len(lines) + 1)
    return b"".join(lines[:i]) + piece + b"".join(lines[i:])


def none(data: bytes, rng: random.Random) -> bytes:
    """No change: the seed as it is (the baseline every seed must pass)."""
    return data


def empty(data: bytes, rng: random.Random) -> bytes:
    """An empty file."""
    return b""


def duplicate_key(data: bytes, rng: random.Random) -> bytes:
    """A YAML key (or XML element) given twice, the copy with another key's value."""
    lines = _lines(data)
    keyed = [i for i, line in enumerate(lines) if _YAML_KEY.match(line.rstrip(b"\r\n"))]
    if not keyed:
        keyed = [i for i, line in enumerate(lines) if _XML_ELEMENT.match(line)]
        if not keyed:
            return duplicate_line(data, rng)
        i = rng.choice(keyed)
        lines.insert(i + 1, lines[i] if _ending(lines[i]) else lines[i] + b"\n")
        return b"".join(lines)
    i, j = rng.choice(keyed), rng.choice(keyed)
    mi = _YAML_KEY.match(lines[i].rstrip(b"\r\n"))
    mj = _YAML_KEY.match(lines[j].rstrip(b"\r\n"))
    assert mi is not None and mj is not None
    indent = mi.group(1) + (b" " * len(mi.group(2)) if mi.group(2) else b"")
    copy = indent + mi.group(3) + b":" + mj.group(4) + (_ending(lines[i]) or b"\n")
    if not _ending(lines[i]):
        lines[i] += b"\n"
    lines.insert(i + 1, copy)
    return b"".join(lines)


#: Content mutations by name.
CONTENT: dict[str, Mutation] = {
    "truncate": truncate, "byte_flip": byte_flip, "delete_line": delete_line,
    "duplicate_line": duplicate_line, "swap_lines": swap_lines, "delete_column": delete_column,
    "duplicate_column": duplicate_column, "swap_columns": swap_columns,
    "special_value": special_value, "crlf": crlf, "utf16": utf16, "bom": bom, "latin1": latin1,
    "junk": junk, "empty": empty, "duplicate_key": duplicate_key, "none": none,
}
#: Content mutations drawn at random (all but ``none``).
DRAWN: tuple[str, ...] = tuple(m for m in CONTENT if m != "none")
#: Mutations of the file itself (each used alone).
WHOLE_FILE: tuple[str, ...] = ("deleted", "folder")
#: What a binary file (``truth.npz``) gets: byte-level mutations only.
BYTE_LEVEL: tuple[str, ...] = ("truncate", "byte_flip", "junk", "empty", "deleted", "folder")
#: Every mutation name (a mutation that finds nothing to change, e.g. columns in YAML, is a no-op).
ALL: tuple[str, ...] = (*CONTENT, *WHOLE_FILE)


@dataclass(frozen=True)
class Case:
    """One fuzz case: reader, seed file, random seed and mutations (printable, replayable)."""

    reader: str
    source: str
    seed: int
    mutations: tuple[str, ...]

    def __str__(self) -> str:
        return f"{self.reader}:{self.source}:{self.seed}:{'+'.join(self.mutations)}"

    @classmethod
    def parse(cls, text: str) -> Case:
        """The case of its printed form ``reader:source:seed:m1+m2``."""
        reader, source, seed, mutations = text.strip().split(":")
        names = tuple(mutations.split("+"))
        unknown = [m for m in names if m not in ALL]
        if unknown:
            raise ValueError(f"unknown mutation {unknown[0]!r}; known: {', '.join(ALL)}")
        return cls(reader, source, int(seed), names)


def draw_mutations(rng: random.Random, binary: bool = False) -> tuple[str, ...]:
    """1-3 mutations: a whole-file one alone about one time in ten, else content mutations."""
    if binary:
        return (rng.choice(BYTE_LEVEL),)
    if rng.random() < 0.1:
        return (rng.choice((*WHOLE_FILE, "empty")),)
    k = rng.choices((1, 2, 3), weights=(6, 3, 1))[0]
    return tuple(rng.choice(DRAWN) for _ in range(k))


def mutate_file(path: Path, mutations: tuple[str, ...], seed: int) -> None:
    """Apply ``mutations`` in order to the file at ``path`` (in place), seeded by ``seed``."""
    rng = random.Random(seed)
    if mutations and mutations[0] in WHOLE_FILE:
        if path.is_dir():
            shutil.rmtree(path)
        else:
            path.unlink()
        if mutations[0] == "folder":
            path.mkdir()
            (path / "unrelated.txt").write_text("a folder where a file was expected\n")
        return
    data = path.read_bytes()
    for name in mutations:
        data = CONTENT[name](data, rng)
    path.write_bytes(data)
