"""A structural check of MATLAB level-5 ``.mat`` files before :func:`scipy.io.loadmat` reads them.

scipy's compiled MAT-5 reader trusts the data-type codes in the file: a corrupted type code
in a numeric array crashes the interpreter (segmentation fault, scipy 1.x) instead of raising.
This walks the element tags of a level-5 file, decompressing ``miCOMPRESSED`` elements, and
checks every numeric and char array (class, type code, size against its dimensions), so a
damaged file gives an :class:`~hlaid.errors.InputError` instead. Cell, struct, object and
sparse arrays are refused: the readers that use this need plain arrays only.
"""

from __future__ import annotations

import struct
import zlib

from ..errors import InputError

MI_MATRIX, MI_COMPRESSED = 14, 15
_NUMERIC_TYPES = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 9: 8, 12: 8, 13: 8}   # miTYPE -> bytes
_CHAR_TYPES = {**_NUMERIC_TYPES, 16: 1, 17: 2, 18: 4}
_NUMERIC_CLASSES = set(range(6, 16))     # mxDOUBLE .. mxUINT64
MX_CHAR = 4
MAX_DEPTH = 2
MAX_INFLATED = 512 * 2**20
"""Largest decompressed size of one element [bytes] accepted."""


def is_mat5(raw: bytes) -> bool:
    """Whether ``raw`` starts with a level-5 MAT header (128 bytes, endian mark at 126)."""
    return len(raw) >= 128 and raw[126:128] in (b"IM", b"MI")


def check_mat5(raw: bytes, source: str) -> None:
    """Raise InputError naming ``source`` if the level-5 MAT file ``raw`` is malformed, or if its
    compressed elements inflate past ``HLAID_MAX_FILE_MB`` or more than the gzip rule allows
    (:data:`hlaid._inputs.GZIP_MAX_RATIO` times beyond :data:`hlaid._inputs.GZIP_FREE_MB`), all of
    them together: checked block by block while inflating, before scipy inflates anything."""
    from .._inputs import GZIP_FREE_MB, GZIP_MAX_RATIO
    from ..limits import max_file_bytes

    endian = "<" if raw[126:128] == b"IM" else ">"
    budget = [min(max_file_bytes(), max(GZIP_FREE_MB * 2**20, GZIP_MAX_RATIO * len(raw)))]
    _walk(raw, 128, len(raw), endian, source, top=True, depth=0, budget=budget)


def _inflate(data: bytes, pos: int, source: str, budget: list[int]) -> bytes:
    """``data`` (zlib) inflated in blocks, each taken from ``budget[0]`` (bytes still allowed)."""
    z = zlib.decompressobj()
    parts, rest = [], data
    try:
        while rest or not z.eof:
            block = z.decompress(rest, 1 << 20)
            rest = z.unconsumed_tail
            budget[0] -= len(block)
            if budget[0] < 0:
                raise _bad(f"compressed element at byte {pos} inflates far more than data compresses (a "
                           "decompression bomb?) or past the file-size limit (set HLAID_MAX_FILE_MB to raise it)",
                           source)
            parts.append(block)
            if not block and not rest:
                break
    except zlib.error as err:
        raise _bad(f"compressed element at byte {pos} does not decompress ({err})", source) from None
    return b"".join(parts)


def _bad(msg: str, source: str):
    return InputError(f"damaged MATLAB file: {msg}", source=source)


def _tag(buf: bytes, pos: int, end: int, e: str, source: str) -> tuple[int, int, int, int]:
    """(type, nbytes, data start, next element start) of the element at ``pos``."""
    if pos + 8 > end:
        raise _bad(f"element tag at byte {pos} runs past the end", source)
    word, nbytes = struct.unpack_from(e + "II", buf, pos)
    if word >> 16:                                  # small data element: 4 bytes of data in the tag
        typ, nbytes = word & 0xFFFF, word >> 16
        if nbytes > 4:
            raise _bad(f"small element at byte {pos} claims {nbytes} bytes", source)
        return typ, nbytes, pos + 4, pos + 8
    start = pos + 8
    if start + nbytes > end:
        raise _bad(f"element at byte {pos} claims {nbytes} bytes but only {end - start} remain", source)
    nxt = start + nbytes if word == MI_COMPRESSED else start + ((nbytes + 7) // 8) * 8
    return word, nbytes, start, min(nxt, end)


def _walk(buf: bytes, pos: int, end: int, e: str, source: str, *, top: bool, depth: int,
          budget: list[int] | None = None) -> None:
    budget = [MAX_INFLATED] if budget is None else budget
    while pos < end:
        if top and end - pos < 8:
            return                                   # trailing padding
        typ, nbytes, start, nxt = _tag(buf, pos, end, e, source)
        if typ == MI_COMPRESSED and top and depth < MAX_DEPTH:
            inner = _inflate(buf[start:start + nbytes], pos, source, budget)
            _walk(inner, 0, len(inner), e, source, top=True, depth=depth + 1, budget=budget)
        elif typ == MI_MATRIX:
            if nbytes:
                _matrix(buf, start, start + nbytes, e, source)
        else:
            raise _bad(f"top-level element at byte {pos} has type {typ}; expected a matrix", source)
        pos = nxt


def _matrix(buf: bytes, pos: int, end: int, e: str, source: str) -> None:
    typ, n, start, pos = _tag(buf, pos, end, e, source)
    if typ != 6 or n != 8:
        raise _bad("array flags missing", source)
    flags = struct.unpack_from(e + "I", buf, start)[0]
    cls, is_complex = flags & 0xFF, bool(flags & 0x800)
    typ, n, start, pos = _tag(buf, pos, end, e, source)
    if typ != 5 or n % 4 or n < 8:
        raise _bad("array dimensions missing", source)
    dims = struct.unpack_from(e + f"{n // 4}i", buf, start)
    if any(d < 0 for d in dims):
        raise _bad(f"negative array dimension {dims}", source)
    typ, n, start, pos = _tag(buf, pos, end, e, source)
    if typ != 1:
        raise _bad("array name missing", source)
    name = buf[start:start + n].decode("latin-1", "replace")
    if cls not in _NUMERIC_CLASSES and cls != MX_CHAR:
        raise _bad(f"variable {name!r} is a MATLAB class-{cls} array (cell, struct, object or sparse); "
                   "expected plain numeric arrays", source)
    count = 1
    for d in dims:
        count *= d
    allowed = _CHAR_TYPES if cls == MX_CHAR else _NUMERIC_TYPES
    for part in ("real", "imaginary")[: 2 if is_complex else 1]:
        typ, n, start, pos = _tag(buf, pos, end, e, source)
        if typ not in allowed:
            raise _bad(f"variable {name!r}: {part} data has type code {typ}", source)
        if typ != 16 and n != count * allowed[typ]:          # UTF-8 text has no fixed width
            raise _bad(f"variable {name!r}: {part} data holds {n} bytes but its dimensions {dims} need "
                       f"{count * allowed[typ]}", source)
