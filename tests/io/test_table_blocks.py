"""A clean block of delimited numbers read at once: the values ``float()`` reads field by field."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ikfusion.io.table import parse_block


def by_field(body: str, delimiter: str) -> np.ndarray:
    """The reference: every field through ``float()``, an empty one NaN."""
    return np.array([[float(v) if v else math.nan for v in line.split(delimiter)]
                     for line in body.split("\n")])


def block(rng: np.random.Generator, delimiter: str, empty: set[int], rows: int = 50,
          width: int = 9) -> str:
    values = rng.normal(size=(rows, width)) * 10.0 ** rng.integers(-3, 4, (1, width))
    return "\n".join(delimiter.join("" if j in empty else f"{v:.6f}"
                                    for j, v in enumerate(row)) for row in values)


@pytest.mark.parametrize("delimiter", ["\t", ";", ","])
@pytest.mark.parametrize("empty", [set(), {1, 2, 3}, {0}, {8}, {0, 4, 8}])
def test_columns_empty_throughout_or_nowhere(rng, delimiter: str, empty: set[int]) -> None:
    body = block(rng, delimiter, empty)
    np.testing.assert_array_equal(parse_block(body, delimiter, 9), by_field(body, delimiter))


def test_empty_fields_scattered_over_columns(rng) -> None:
    lines = block(rng, "\t", {2, 3}).split("\n")
    lines[7] = "\t".join("" if j == 5 else v for j, v in enumerate(lines[7].split("\t")))
    lines[9] = "\t".join(v or "1.5" for v in lines[9].split("\t"))  # column 2 filled once
    body = "\n".join(lines)
    np.testing.assert_array_equal(parse_block(body, "\t", 9), by_field(body, "\t"))


def test_ragged_lines_and_words_are_left_to_the_line_by_line_reader(rng) -> None:
    lines = block(rng, "\t", {1, 2}).split("\n")
    short = lines.copy()
    short[3] = short[3].rsplit("\t", 1)[0]
    short[4] = short[4] + "\t0.5"  # the field count of the block stays the same
    assert parse_block("\n".join(short), "\t", 9) is None
    word = lines.copy()
    word[6] = word[6].replace("\t\t\t", "\t\tabc\t", 1)
    assert parse_block("\n".join(word), "\t", 9) is None
    word = lines.copy()
    word[6] = "x" + word[6]
    assert parse_block("\n".join(word), "\t", 9) is None


def test_real_export_as_field_by_field(shared_data) -> None:
    path = next((shared_data / "xsens" / "opensense_walk").glob("*.txt"))
    lines = path.read_text().split("\n")
    header = next(k for k, line in enumerate(lines) if line.startswith("PacketCounter"))
    body = "\n".join(lines[header + 1:]).rstrip("\n")
    width = len(lines[header].split("\t"))
    np.testing.assert_array_equal(parse_block(body, "\t", width), by_field(body, "\t"))
