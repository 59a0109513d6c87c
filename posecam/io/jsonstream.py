"""A JSON document read as a stream: objects and arrays entered one key or item at a time,
leaves (a person, a number) decoded by the json module's own scanner. Memory holds a window
of the text (a few MB), never the whole document, so a pose file of any length reads in flat
memory and a reader can refuse a list before it is built (a frame of a million people).

    stream = JsonStream(file, "poses.json")
    for key in stream.keys():                  # {"joints": [...], "inputs": [...]}
        if key == "inputs":
            for n in stream.items(most=100, field="poses.json inputs"):
                ...                            # read item n with keys(), items() or value()
        else:
            value = stream.value()
    stream.end()
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from typing import TextIO

from posecam.errors import InputError

WINDOW = 4 << 20           # characters: the largest leaf value read at once
_SPACE = re.compile(r"[ \t\n\r]*")


def _no_constant(name: str) -> None:
    raise ValueError(f"{name} is not a JSON number")


class JsonStream:
    def __init__(self, f: TextIO, where: str):
        self.f, self.where = f, where
        self.text, self.i, self.offset, self.eof = "", 0, 0, False
        self._scan = json.JSONDecoder(parse_constant=_no_constant).scan_once

    def error(self, message: str) -> InputError:
        return InputError(f"{self.where} is not a posecam pose file ({message} at character {self.offset + self.i})")

    def _fill(self) -> None:
        if self.eof or len(self.text) - self.i >= WINDOW:
            return
        chunk = self.f.read(WINDOW)
        self.text, self.offset, self.i = self.text[self.i:] + chunk, self.offset + self.i, 0
        self.eof = not chunk

    def _peek(self) -> str:
        while True:
            self._fill()
            self.i = _SPACE.match(self.text, self.i).end()
            if self.i < len(self.text) or self.eof:
                return self.text[self.i:self.i + 1]

    def _expect(self, char: str) -> None:
        if self._peek() != char:
            got = self.text[self.i:self.i + 1] or "the end of the file"
            raise self.error(f"expected {char!r}, got {got!r}")
        self.i += 1

    def value(self) -> object:
        """The next value, decoded whole (NaN and Infinity refused)."""
        self._peek()
        try:
            value, end = self._scan(self.text, self.i)
        except StopIteration:
            raise self.error("expected a value") from None
        except json.JSONDecodeError as exc:
            raise self.error(exc.msg) from None
        except ValueError as exc:
            raise self.error(str(exc)) from None
        if end >= len(self.text) and not self.eof:
            raise self.error(f"a value longer than {WINDOW >> 20} MB")
        self.i = end
        return value

    def _members(self, opening: str, closing: str) -> Iterator[int]:
        """Enter an object or an array: yield the count of members read so far before each;
        the caller reads the member before the next."""
        self._expect(opening)
        if self._peek() == closing:
            self.i += 1
            return
        n = 0
        while True:
            yield n
            n += 1
            if self._peek() != ",":
                self._expect(closing)
                return
            self.i += 1

    def keys(self) -> Iterator[str]:
        """Enter an object: yield each key; the caller reads its value before the next."""
        for _ in self._members("{", "}"):
            if self._peek() != '"':
                raise self.error("expected a key")
            key = self.value()
            self._expect(":")
            yield key

    def items(self, most: int, field: str) -> Iterator[int]:
        """Enter an array: yield the index of each item; the caller reads the item before the
        next. More than `most` items: InputError naming `field` (the file and the place in it),
        before the one over is read."""
        for n in self._members("[", "]"):
            if n >= most:
                raise InputError(f"{field}: must hold at most {most} entries")
            yield n

    def end(self) -> None:
        if self._peek():
            raise self.error("extra data after the document")
