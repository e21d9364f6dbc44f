"""Bounded readers for every file a user hands the suite: text, YAML, JSON, image headers.

Each reader checks its limits (``excavation_common.limits``) before it allocates anything
from the file's contents: the size before reading, the nesting while parsing, an image's
pixel count from its header before decoding. Ambiguous files are refused too: a key given
twice in one YAML or JSON mapping, YAML aliases (``*name``, which let a small file expand
into a huge one), ``NaN`` and ``Infinity`` in JSON.

Every failure raises ``error(path, field, value, reason)``, the caller's subclass of
:class:`~excavation_common.errors.FieldError`, so a loader's caller sees one error type
that names the file, the field and the limit. Pure module: no ``rclpy``.
"""

from __future__ import annotations

import json
import math
import os
import stat
import struct
from pathlib import Path

import yaml

from excavation_common.errors import FieldError
from excavation_common.limits import (
    MAX_IMAGE_BYTES,
    MAX_IMAGE_PIXELS,
    MAX_IMAGE_SIDE,
    MAX_NESTING,
    MAX_TEXT_BYTES,
)

ErrorType = type[FieldError]


def read_bytes_bounded(
    path: str | Path, max_bytes: int = MAX_TEXT_BYTES, error: ErrorType = FieldError
) -> bytes:
    """The bytes of a regular file of at most ``max_bytes``.

    The size is checked on the file's metadata before reading, and at most
    ``max_bytes + 1`` bytes are ever read (a file that grows meanwhile is refused too).

    Raises:
        FieldError: ``error`` for a missing, unreadable, special or too large file.
    """
    label = str(path)
    try:
        with open(path, "rb") as f:
            info = os.fstat(f.fileno())
            if not stat.S_ISREG(info.st_mode):
                raise error(label, "<file>", label, "is not a regular file")
            if info.st_size > max_bytes:
                raise error(
                    label,
                    "<file>",
                    f"{info.st_size} bytes",
                    f"is larger than the limit of {max_bytes} bytes",
                )
            data = f.read(max_bytes + 1)
    except FileNotFoundError:
        raise error(label, "<file>", label, "does not exist") from None
    except IsADirectoryError:
        raise error(label, "<file>", label, "cannot be read: it is a directory") from None
    except OSError as exc:
        raise error(label, "<file>", label, f"cannot be read: {exc.strerror or exc}") from None
    if len(data) > max_bytes:
        raise error(label, "<file>", "growing", f"is larger than the limit of {max_bytes} bytes")
    return data


def read_text_bounded(
    path: str | Path, max_bytes: int = MAX_TEXT_BYTES, error: ErrorType = FieldError
) -> str:
    """The UTF-8 text of a file of at most ``max_bytes`` (see :func:`read_bytes_bounded`).

    Raises:
        FieldError: ``error`` for a missing, too large or non-UTF-8 file.
    """
    label = str(path)
    data = read_bytes_bounded(path, max_bytes, error)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(
            label, "<file>", f"byte {exc.start}", "cannot be read: not UTF-8 text (a binary file?)"
        ) from None


# --- YAML -----------------------------------------------------------------------------------


class _YamlRefused(Exception):
    """Raised inside the loader; turned into the caller's error with the file name."""

    def __init__(self, field: str, value: object, reason: str) -> None:
        super().__init__(reason)
        self.field = field
        self.value = value
        self.reason = reason


class _BoundedSafeLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses duplicate keys, aliases and deep nesting."""

    max_depth = MAX_NESTING

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):  # noqa: D102 (PyYAML hook)
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise _YamlRefused(
                _where(event.start_mark),
                f"*{event.anchor}",
                "YAML aliases are not allowed (write the value out)",
            )
        self._depth += 1
        if self._depth > self.max_depth:
            raise _YamlRefused(
                _where(self.peek_event().start_mark),
                f"{self._depth} levels",
                f"is nested deeper than the limit of {self.max_depth} levels",
            )
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node, deep=False):  # noqa: D102 (PyYAML hook)
        if isinstance(node, yaml.MappingNode):
            self.flatten_mapping(node)
            seen: dict[object, str] = {}
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=True)
                try:
                    first = seen.get(key)
                except TypeError:
                    continue  # unhashable: SafeConstructor reports it
                mark = key_node.start_mark
                where = f"line {mark.line + 1} column {mark.column + 1}"
                if first is not None:
                    raise _YamlRefused(
                        str(key), where, f"is given twice (first at {first}); a key may appear once"
                    )
                seen[key] = where
        return super().construct_mapping(node, deep)


def _where(mark: yaml.Mark | None) -> str:
    return f"line {mark.line + 1}" if mark is not None else "<yaml>"


def parse_yaml(
    text: str,
    label: str = "<memory>",
    error: ErrorType = FieldError,
    max_depth: int = MAX_NESTING,
) -> object:
    """Parse YAML text safely (no Python objects), refusing ambiguous or deep documents.

    Args:
        text: The document.
        label: File name for messages.
        error: The caller's :class:`FieldError` subclass.
        max_depth: Deepest nesting allowed (a scalar at the top counts as 1).

    Raises:
        FieldError: ``error`` naming the line of a syntax error, a duplicate key, an
            alias, or nesting beyond ``max_depth``.
    """
    loader = _BoundedSafeLoader(text)
    loader.max_depth = max_depth
    try:
        return loader.get_single_data()
    except _YamlRefused as exc:
        raise error(label, exc.field, exc.value, exc.reason) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        raise error(label, _where(mark), None, f"is not valid YAML: {exc.problem}") from None
    except yaml.YAMLError as exc:
        raise error(label, "<yaml>", None, f"is not valid YAML: {exc}") from None
    except (ValueError, OverflowError) as exc:  # e.g. a timestamp with month 13
        raise error(label, "<yaml>", None, f"holds a value that cannot be read: {exc}") from None
    except RecursionError:
        raise error(label, "<yaml>", None, "is nested too deeply") from None
    finally:
        loader.dispose()


def load_yaml(
    path: str | Path,
    error: ErrorType = FieldError,
    max_bytes: int = MAX_TEXT_BYTES,
    max_depth: int = MAX_NESTING,
) -> object:
    """Read and parse a YAML file within the size and nesting limits.

    Raises:
        FieldError: ``error`` for any problem (see :func:`read_text_bounded`,
            :func:`parse_yaml`).
    """
    return parse_yaml(read_text_bounded(path, max_bytes, error), str(path), error, max_depth)


# --- JSON -----------------------------------------------------------------------------------


def _depth(value: object) -> int:
    """Nesting depth of parsed JSON, without recursion."""
    deepest = 0
    stack = [(value, 1)]
    while stack:
        item, level = stack.pop()
        deepest = max(deepest, level)
        if isinstance(item, dict):
            stack.extend((v, level + 1) for v in item.values())
        elif isinstance(item, list):
            stack.extend((v, level + 1) for v in item)
    return deepest


def parse_json(
    text: str,
    label: str = "<memory>",
    error: ErrorType = FieldError,
    max_depth: int = MAX_NESTING,
) -> object:
    """Parse JSON text, refusing duplicate keys, ``NaN`` / ``Infinity`` and deep nesting.

    Raises:
        FieldError: ``error`` naming the line and column of a syntax error, the key given
            twice, the constant, or the nesting limit.
    """

    def pairs(items: list[tuple[str, object]]) -> dict:
        out: dict = {}
        for key, value in items:
            if key in out:
                raise error(label, key, None, "is given twice in one object; a key may appear once")
            out[key] = value
        return out

    def constant(name: str) -> float:
        raise error(label, "<json>", name, "NaN and Infinity are not allowed")

    def number(text: str) -> float:
        value = float(text)
        if not math.isfinite(value):
            raise error(label, "<json>", text, "is too large for a 64-bit float")
        return value

    try:
        data = json.loads(
            text, object_pairs_hook=pairs, parse_constant=constant, parse_float=number
        )
    except FieldError:
        raise
    except json.JSONDecodeError as exc:
        raise error(
            label, f"line {exc.lineno} column {exc.colno}", None, f"is not valid JSON: {exc.msg}"
        ) from None
    except RecursionError:
        raise error(
            label, "<json>", None, f"is nested deeper than the limit of {max_depth} levels"
        ) from None
    except ValueError as exc:  # integers of more than 4300 digits
        raise error(label, "<json>", None, f"cannot be parsed: {exc}") from None
    depth = _depth(data)
    if depth > max_depth:
        raise error(
            label, "<json>", depth, f"is nested deeper than the limit of {max_depth} levels"
        )
    return data


def load_json(
    path: str | Path,
    error: ErrorType = FieldError,
    max_bytes: int = MAX_TEXT_BYTES,
    max_depth: int = MAX_NESTING,
) -> object:
    """Read and parse a JSON file within the size and nesting limits.

    Raises:
        FieldError: ``error`` for any problem (see :func:`read_text_bounded`,
            :func:`parse_json`).
    """
    return parse_json(read_text_bounded(path, max_bytes, error), str(path), error, max_depth)


# --- images ---------------------------------------------------------------------------------

_PNG = b"\x89PNG\r\n\x1a\n"
_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
_HEADER_BYTES = 1 << 16
"""How far into a file the header reader looks (a JPEG's EXIF may precede its frame)."""


def _jpeg_size(head: bytes) -> tuple[int, int] | None:
    i = 2
    while i + 4 <= len(head):
        if head[i] != 0xFF:
            return None
        marker = head[i + 1]
        if marker == 0xFF:  # fill byte
            i += 1
            continue
        if marker in (0x01, *range(0xD0, 0xD9)):  # stand-alone markers
            i += 2
            continue
        (length,) = struct.unpack(">H", head[i + 2 : i + 4])
        if marker in _JPEG_SOF:
            if i + 9 > len(head):
                return None
            height, width = struct.unpack(">HH", head[i + 5 : i + 9])
            return width, height
        i += 2 + length
    return None


def image_size(path: str | Path, error: ErrorType = FieldError) -> tuple[int, int]:
    """``(width, height)`` of a PNG, JPEG or BMP file, read from its header only.

    Raises:
        FieldError: ``error`` for a missing file, another format, or a broken header.
    """
    label = str(path)
    try:
        with open(path, "rb") as f:
            if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
                raise error(label, "<file>", label, "is not a regular file")
            head = f.read(_HEADER_BYTES)
    except FileNotFoundError:
        raise error(label, "<file>", label, "does not exist") from None
    except OSError as exc:
        raise error(label, "<file>", label, f"cannot be read: {exc.strerror or exc}") from None
    size: tuple[int, int] | None = None
    if head.startswith(_PNG):
        if len(head) >= 24 and head[12:16] == b"IHDR":
            size = struct.unpack(">II", head[16:24])
        kind = "PNG"
    elif head.startswith(b"\xff\xd8"):
        size = _jpeg_size(head)
        kind = "JPEG"
    elif head.startswith(b"BM"):
        if len(head) >= 26:
            w, h = struct.unpack("<ii", head[18:26])
            size = (abs(w), abs(h))
        kind = "BMP"
    else:
        raise error(label, "<image>", head[:8], "is not a PNG, JPEG or BMP file")
    if size is None:
        raise error(label, "<image>", kind, "has a broken or truncated header")
    return int(size[0]), int(size[1])


def check_image(
    path: str | Path,
    error: ErrorType = FieldError,
    max_pixels: int = MAX_IMAGE_PIXELS,
    max_side: int = MAX_IMAGE_SIDE,
    max_bytes: int = MAX_IMAGE_BYTES,
) -> tuple[int, int]:
    """Check an image's file size and header dimensions before anything decodes it.

    Returns:
        ``(width, height)`` from the header.

    Raises:
        FieldError: ``error`` naming the file, the size and the limit it exceeds.
    """
    label = str(path)
    width, height = image_size(path, error)
    if width < 1 or height < 1:
        raise error(label, "<image>", f"{width} x {height}", "has no pixels")
    if max(width, height) > max_side:
        raise error(
            label,
            "<image>",
            f"{width} x {height} pixels",
            f"is larger than the limit of {max_side} pixels a side",
        )
    if width * height > max_pixels:
        raise error(
            label,
            "<image>",
            f"{width} x {height} pixels",
            f"has more than the limit of {max_pixels} pixels",
        )
    file_size = Path(path).stat().st_size
    if file_size > max_bytes:
        raise error(
            label, "<file>", f"{file_size} bytes", f"is larger than the limit of {max_bytes} bytes"
        )
    return width, height
