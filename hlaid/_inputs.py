"""Reading input files: the one path every file hlaid opens goes through.

Measurements, records, configs, clones, run summaries, classifier cache entries and fleet
results are all opened by :func:`open_input` and read by the functions below, which hold every
file to the same rules before a byte is read or an array allocated:

- only a regular file is read: a folder, a FIFO, a device (``/dev/zero``) or a socket is refused,
  judged by the descriptor actually opened (a FIFO is opened without waiting for a writer), so
  a symlink to a device is refused too;
- at most ``HLAID_MAX_FILE_MB`` (:mod:`hlaid.limits`) is read, also after gunzip and for the
  inflated members of an NPZ;
- JSON is nested at most :data:`MAX_JSON_DEPTH` levels, and an integer of more than
  :data:`MAX_JSON_DIGITS` digits is read as a float (the field it is given to then refuses it);
- every array of an NPZ is checked against its member's size before it is allocated (a tiny
  file whose header claims 10^10 samples is refused, not inflated).

Third-party readers that take a path (``scipy.io.loadmat``, ObsPy) are given a file only after
:func:`check_readable_file`.

Every file opened this way while a command runs (:func:`recording`, which the command line sets up)
is an input of the run, however it was named: on the command line, in a config, in a columns YAML,
in a records folder. :mod:`hlaid._fileio` refuses an output that is, or holds, one of them. Files
hlaid keeps for itself (output markers, classifier cache entries, a fleet's stored results) are read
inside :func:`own_files` and are no inputs.
"""

from __future__ import annotations

import contextlib
import errno
import gzip
import hashlib
import io
import json
import math
import os
import stat
import threading
import zipfile
import zlib
from collections.abc import Iterator
from typing import IO, Any

from .errors import InputError, one_line
from .limits import file_limit_text, max_file_bytes

MAX_JSON_DEPTH = 64
"""Deepest nesting of lists and mappings in a JSON file hlaid reads (its own files nest < 10)."""

MAX_JSON_DIGITS = 40
"""Longest integer (in digits) that a JSON file hlaid reads gives as an integer."""

GZIP_FREE_MB = 16
"""A gzipped input may inflate to this many MiB whatever its ratio (see :data:`GZIP_MAX_RATIO`)."""

GZIP_MAX_RATIO = 100
"""Beyond :data:`GZIP_FREE_MB`, a gzipped input may inflate to at most this many times the
compressed bytes read so far: data compresses 2-10 times, a gzip bomb a thousand times, and is
refused after a few MiB instead of after ``HLAID_MAX_FILE_MB``."""


# ---------------------------------------------------------------------------- inputs of the run
_inputs: dict[tuple[int, int], str] | None = None  # (device, inode) -> real path, while recording
_rewritten: set[str] = set()  # real paths the command rewrites by design (:func:`rewrites`)
_own = threading.local()


@contextlib.contextmanager
def recording() -> Iterator[None]:
    """Record every file opened inside the block as an input of the run (:func:`run_inputs`)."""
    global _inputs
    before, _inputs = _inputs, {}
    try:
        yield
    finally:
        _inputs = before


@contextlib.contextmanager
def own_files() -> Iterator[None]:
    """Files read inside the block (in this thread) are hlaid's own (markers, cache entries,
    stored results it rewrites), not inputs of the run."""
    depth = getattr(_own, "depth", 0)
    _own.depth = depth + 1
    try:
        yield
    finally:
        _own.depth = depth


@contextlib.contextmanager
def rewrites(*paths: str | os.PathLike) -> Iterator[None]:
    """The files ``paths`` are read and rewritten in place by design inside the block (the summary
    of a run folder that ``hlaid loss`` adds its block to): reading them makes no input of them."""
    added = {os.path.realpath(os.path.abspath(p)) for p in paths} - _rewritten
    _rewritten.update(added)
    try:
        yield
    finally:
        _rewritten.difference_update(added)


def _register(path: str | os.PathLike, st: os.stat_result) -> None:
    own: int = getattr(_own, "depth", 0)
    if _inputs is None or own > 0 or not stat.S_ISREG(st.st_mode):
        return
    real = os.path.realpath(os.path.abspath(path))
    if real not in _rewritten:
        _inputs.setdefault((st.st_dev, st.st_ino), real)


def run_inputs() -> list[str]:
    """The real paths of the files opened as inputs since :func:`recording` began (none outside it)."""
    return list(_inputs.values()) if _inputs else []


def input_named(path: str | os.PathLike) -> str | None:
    """The input of the run that ``path`` is (the same file, also through a link), or None."""
    if not _inputs:
        return None
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        st = None
    if st is not None and (st.st_dev, st.st_ino) in _inputs:
        return _inputs[(st.st_dev, st.st_ino)]
    real = os.path.realpath(os.path.abspath(path))
    return real if real in _inputs.values() else None


class NotTextError(InputError):
    """A file read as text holds binary data (a format sniffer may try the next format)."""


def _special(mode: int) -> str | None:
    """What a file of ``mode`` is when it is neither a regular file nor a folder, else None."""
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    return ("a character device" if stat.S_ISCHR(mode) else "a block device" if stat.S_ISBLK(mode)
            else "a FIFO (named pipe)" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode)
            else "a special file")


def _check_stat(st: os.stat_result, source: str) -> int:
    kind = _special(st.st_mode)
    if kind is not None:
        raise InputError(f"is {kind}; expected a regular file", source=source)
    top = max_file_bytes()
    if stat.S_ISREG(st.st_mode) and st.st_size > top:
        raise InputError(f"is {st.st_size / 2**20:.3g} MiB, over {file_limit_text()}", source=source)
    return int(st.st_size)


def check_readable_file(path: str | os.PathLike) -> int:
    """Refuse anything but a regular file within the size limit, before a third-party reader
    opens it; returns its size. A missing path or a folder is left to the caller's own message."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return 0
    if stat.S_ISDIR(st.st_mode):
        return 0
    size = _check_stat(st, str(path))
    _register(path, st)  # a third-party reader opens it next
    return size


def check_input(path: str | os.PathLike) -> None:
    """Refuse a missing input, or one that is neither a folder nor a regular file within the size
    limit, before any reader (and the libraries it needs) is loaded."""
    if not os.path.lexists(path):
        raise InputError("file not found", source=str(path))
    if os.path.islink(path) and not os.path.exists(path):
        raise InputError("is a broken symbolic link", source=str(path))
    check_readable_file(path)


@contextlib.contextmanager
def open_input(path: str | os.PathLike) -> Iterator[IO[bytes]]:
    """A regular file opened for reading (binary), within ``HLAID_MAX_FILE_MB``.

    Missing files, folders, FIFOs, devices and sockets are :class:`InputError` s naming the
    path, raised before anything is read (a FIFO is opened non-blocking, so it cannot hang).
    """
    source = str(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise InputError("file not found", source=source) from None
    except IsADirectoryError:
        raise InputError("is a folder; expected a file", source=source) from None
    except PermissionError:
        raise InputError("cannot be read (permission denied)", source=source) from None
    except (OSError, ValueError) as err:
        raise InputError(f"cannot be opened ({getattr(err, 'strerror', None) or err})", source=source) from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise InputError("is a folder; expected a file", source=source)
        _check_stat(st, source)
        _register(path, st)
        fh = os.fdopen(fd, "rb")  # left non-blocking: a pseudo-file that waits (/proc/kmsg) cannot hang a read
    except BaseException:
        os.close(fd)
        raise
    with fh:
        yield fh


def _unreadable(err: OSError) -> str:
    if isinstance(err, BlockingIOError) or err.errno in (errno.EAGAIN, errno.EWOULDBLOCK):
        return ("cannot be read: it waits for data instead of holding any (a kernel or device pseudo-file such as "
                "/proc/kmsg?); expected a data file")
    return f"cannot be read ({err.strerror or err})"


DATA_LINES = "data"
"""``read_text(path, max_lines=DATA_LINES)``: a data file of one sample per line at most, bounded by
``HLAID_MAX_SAMPLES`` (and a header's worth of lines): refused while it is read, not after."""

HEADER_LINES = 1000
"""Lines a data file may hold beyond ``HLAID_MAX_SAMPLES`` (headers, comments)."""

MAX_LINE_BYTES = 1 << 20
"""Bytes one line of a data file may hold (a row of 10,000 channels of 100 characters): a longer one
is refused as it is read, after a few MiB, not once the whole file is in memory."""


def _line_limit(max_lines: int | str | None) -> tuple[int | None, str]:
    if max_lines is None:
        return None, ""
    if max_lines == DATA_LINES:
        from .limits import limit

        top = int(limit("SAMPLES"))
        return top + HEADER_LINES, (f"a record holds at most {top:,} samples, one a line at most (set "
                                    "HLAID_MAX_SAMPLES to raise the limit)")
    return int(max_lines), "more than hlaid reads from such a file"


class _Lines:
    """Counts the lines of the blocks of a file as they are read; refuses past ``top``."""

    def __init__(self, max_lines, source: str):
        self.top, self.why = _line_limit(max_lines)
        self.n, self.source, self.run = 0, source, 0

    def add(self, block: bytes) -> None:
        if self.top is None:
            return
        k = block.count(b"\n")
        self.n += k
        if self.n > self.top:
            raise InputError(f"holds more than {self.top:,} lines; {self.why}", source=self.source)
        last = block.rfind(b"\n")  # the bytes of the line still open at the block's end
        self.run = len(block) - last - 1 if k else self.run + len(block)
        longest = max(self.run, _longest_line(block) if k else 0)
        if longest > MAX_LINE_BYTES:
            raise InputError(f"holds a line of more than {MAX_LINE_BYTES // 2**20} MiB ({longest / 2**20:.3g} MiB read "
                             "of it); a data file holds one sample a line", source=self.source)


def _longest_line(block: bytes) -> int:
    """Bytes of the longest complete line within ``block``, or 0 where none can reach
    :data:`MAX_LINE_BYTES` (cheap: a scan of its lines only when some half of that holds no newline)."""
    if len(block) <= MAX_LINE_BYTES:
        return 0
    half = MAX_LINE_BYTES // 2  # a newline in every aligned half-window: every line is shorter than the limit
    if all(block.find(b"\n", i, i + half) >= 0 for i in range(0, len(block) - half + 1, half)):
        return 0
    longest, start = 0, 0
    while (end := block.find(b"\n", start)) >= 0:
        longest = max(longest, end - start)
        start = end + 1
    return longest


def read_bytes(path: str | os.PathLike, *, max_lines: int | str | None = None) -> bytes:
    """The bytes of a regular file within ``HLAID_MAX_FILE_MB`` (see :func:`open_input`), read in
    blocks; with ``max_lines`` (a count, or :data:`DATA_LINES`) refused as soon as it holds more
    lines than that (a gzipped file's lines are counted as it is inflated, :func:`read_text`)."""
    top = max_file_bytes()
    parts, size = [], 0
    with open_input(path) as fh:
        lines = None
        try:
            while True:
                block = fh.read(min(1 << 22, top + 1 - size))
                if block is None:  # nothing to read yet: a pseudo-file that waits for data
                    raise BlockingIOError(errno.EAGAIN, "")
                if not block:
                    break
                if size == 0:
                    lines = _Lines(None if block[:2] == b"\x1f\x8b" else max_lines, str(path))
                parts.append(block)
                size += len(block)
                if lines is not None:
                    lines.add(block)
                if size > top:
                    break
        except OSError as err:
            raise InputError(_unreadable(err), source=str(path)) from None
    if size > top:  # it grew after it was opened
        raise InputError(f"holds more than {file_limit_text()}", source=str(path))
    return b"".join(parts)


def read_text(path: str | os.PathLike, *, max_lines: int | str | None = None) -> str:
    """Text of a file, transparently gunzipped (inflated size limited too); binary files refused.
    ``max_lines``: see :func:`read_bytes` (a data file: :data:`DATA_LINES`)."""
    raw = read_bytes(path, max_lines=max_lines)
    if raw[:2] == b"\x1f\x8b":
        raw = gunzip(raw, str(path), max_lines=max_lines)
    if b"\x00" in raw[:4096]:
        raise NotTextError("is a binary file; expected text", source=str(path))
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def gunzip(raw: bytes, source: str, *, max_lines: int | str | None = None) -> bytes:
    """``raw`` (gzip) inflated in blocks, refused as soon as it passes ``HLAID_MAX_FILE_MB``, inflates
    more than :data:`GZIP_MAX_RATIO` times beyond :data:`GZIP_FREE_MB` (a gzip bomb is refused after
    a few MiB, not after it filled memory) or holds more than ``max_lines`` lines."""
    top, free = max_file_bytes(), GZIP_FREE_MB * 2**20
    lines = _Lines(max_lines, source)
    src = io.BytesIO(raw)
    parts, size = [], 0
    try:
        with gzip.GzipFile(fileobj=src) as gz:
            while block := gz.read(1 << 20):
                parts.append(block)
                size += len(block)
                lines.add(block)
                if size > top:
                    raise InputError(f"holds more than {file_limit_text()}", source=source)
                if size > free and size > GZIP_MAX_RATIO * max(src.tell(), 1):
                    raise InputError(f"inflates more than {GZIP_MAX_RATIO} times ({size / 2**20:.3g} MiB from "
                                     f"{src.tell() / 2**10:.3g} KiB read so far): no data file compresses so well "
                                     "(a gzip bomb?)", source=source)
    except (OSError, EOFError, zlib.error) as err:
        raise InputError(f"cannot read it as gzip ({one_line(err, 80)})", source=source) from None
    return b"".join(parts)


def read_head(path: str | os.PathLike, n_bytes: int = 1 << 16) -> str:
    """The first ``n_bytes`` of a file's text (gunzipped where it is gzip), for a format to be told
    from its first lines without reading the rest; a binary file is :class:`NotTextError`."""
    with open_input(path) as fh:
        try:
            raw = fh.read(n_bytes) or b""
        except OSError as err:
            raise InputError(_unreadable(err), source=str(path)) from None
        if raw[:2] == b"\x1f\x8b":
            fh.seek(0)
            try:
                with gzip.GzipFile(fileobj=fh) as gz:
                    raw = gz.read(n_bytes)
            except (OSError, EOFError, zlib.error) as err:
                raise InputError(f"cannot read it as gzip ({one_line(err, 80)})",
                                 source=str(path)) from None
    if b"\x00" in raw[:4096]:
        raise NotTextError("is a binary file; expected text", source=str(path))
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def file_sha256(path: str | os.PathLike) -> str:
    """SHA-256 (hex) of a regular file within ``HLAID_MAX_FILE_MB``, read in blocks."""
    h = hashlib.sha256()
    with open_input(path) as fh:
        try:
            while block := fh.read(1 << 20):
                h.update(block)
            if block is None:
                raise BlockingIOError(errno.EAGAIN, "")
        except OSError as err:
            raise InputError(_unreadable(err), source=str(path)) from None
    return h.hexdigest()


# ---------------------------------------------------------------------------- JSON
def _bounded_int(text: str) -> int | float:
    """An integer of at most :data:`MAX_JSON_DIGITS` digits; a longer one becomes a float (inf
    beyond 1e308), which the field it is given to refuses by name (no 5000-digit int is built)."""
    if len(text.lstrip("-")) > MAX_JSON_DIGITS:
        return float(text)
    return int(text)


def _check_depth(obj: Any) -> None:
    stack = [(obj, 1)]
    while stack:
        o, depth = stack.pop()
        if depth > MAX_JSON_DEPTH:
            raise InputError(f"is nested more than {MAX_JSON_DEPTH} levels deep")
        items = o.values() if isinstance(o, dict) else o if isinstance(o, list) else ()
        stack.extend((x, depth + 1) for x in items if isinstance(x, (dict, list)))


class _DuplicateKey(ValueError):
    pass


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict:
    out = dict(pairs)
    if len(out) != len(pairs):
        seen: set[str] = set()
        key = next(k for k, _ in pairs if k in seen or seen.add(k))  # type: ignore[func-returns-value]
        raise _DuplicateKey(f"key {key!r} appears twice in one object" if len(key) <= 40 and key.isprintable()
                            else "a key appears twice in one object")
    return out


def loads_json(text: str, source: str | None = None) -> Any:
    """Parse JSON text with bounded depth and integer length, each key once per object; errors
    name ``source`` and the line."""
    try:
        obj = json.loads(text, parse_int=_bounded_int, object_pairs_hook=_no_duplicates)  # type: ignore[arg-type]
        _check_depth(obj)
    except InputError as err:
        raise InputError(f"not a JSON file hlaid reads: {err}", source=source) from None
    except RecursionError:
        raise InputError(f"not a JSON file hlaid reads: it is nested more than {MAX_JSON_DEPTH} levels deep",
                         source=source) from None
    except json.JSONDecodeError as err:
        raise InputError(f"not valid JSON (line {err.lineno}: {err.msg})", source=source) from None
    except _DuplicateKey as err:
        raise InputError(f"not a JSON file hlaid reads: {err}", source=source) from None
    return obj


def read_json(path: str | os.PathLike) -> Any:
    """The JSON value in a file (read by :func:`read_text`, parsed by :func:`loads_json`)."""
    return loads_json(read_text(path), str(path))


# ---------------------------------------------------------------------------- NPZ
def _inflated_total(zf: zipfile.ZipFile, source: str) -> None:
    total = sum(info.file_size for info in zf.infolist())
    if total > max_file_bytes():
        raise InputError(f"inflates to {total / 2**20:.3g} MiB, over {file_limit_text()}", source=source)


MAX_MEMBERS = 10_000
"""Members a zip archive hlaid reads (an NPZ of named arrays) may hold: a measurement has a few, an
NPZ of 100,000 tiny members is refused from the count its end record gives, before its
directory is read (which alone takes seconds)."""


def _member_count(fh: IO[bytes]) -> int | None:
    """The number of members the end record of the zip archive open in ``fh`` declares (zip64
    too), or None where there is no such record (the reader then says what the file is)."""
    import struct
    try:
        fh.seek(0, os.SEEK_END)
        size = fh.tell()
        fh.seek(max(size - (22 + 65535), 0))
        tail = fh.read()
    except OSError:
        return None
    at = tail.rfind(b"PK\x05\x06")
    if at < 0 or at + 22 > len(tail):
        return None
    n = struct.unpack("<H", tail[at + 10:at + 12])[0]
    loc = at - 20
    if n == 0xFFFF and loc >= 0 and tail[loc:loc + 4] == b"PK\x06\x07":
        try:
            fh.seek(struct.unpack("<Q", tail[loc + 8:loc + 16])[0])
            rec = fh.read(56)
        except (OSError, OverflowError, ValueError):
            return None
        if rec[:4] == b"PK\x06\x06" and len(rec) == 56:
            n = struct.unpack("<Q", rec[32:40])[0]
    fh.seek(0)
    return int(n)


def _check_members(fh: IO[bytes], source: str) -> None:
    n = _member_count(fh)
    if n is not None and n > MAX_MEMBERS:
        raise InputError(f"is a zip archive of {n:,} members; an NPZ hlaid reads holds at most {MAX_MEMBERS:,} arrays",
                         source=source)


def check_archive(path: str | os.PathLike) -> None:
    """Refuse a zip archive (an NPZ) of more than :data:`MAX_MEMBERS` members or whose members
    inflate past ``HLAID_MAX_FILE_MB``, before inflating any; an unreadable archive is left to the
    reader's own message."""
    try:
        with open_input(path) as fh:
            _check_members(fh, str(path))
            with zipfile.ZipFile(fh) as zf:
                _inflated_total(zf, str(path))
    except (zipfile.BadZipFile, OSError, ValueError) as err:
        if isinstance(err, InputError):
            raise
        return


def _npy_header(member: IO[bytes], name: str, size: int, source: str):
    """``(shape, fortran_order, dtype)`` of an ``.npy`` member, checked against its ``size``."""
    import numpy as np
    fmt = np.lib.format
    try:
        version = fmt.read_magic(member)
        if version == (1, 0):
            shape, fortran, dtype = fmt.read_array_header_1_0(member)
        elif version == (2, 0):
            shape, fortran, dtype = fmt.read_array_header_2_0(member)
        else:
            raise ValueError(f"array format version {version}")
        header = member.tell()
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as err:
        raise InputError(f"array {name!r} has no readable header ({one_line(err, 80)})",
                         source=source) from None
    if dtype.hasobject or dtype.kind not in "biufcUS" or dtype.itemsize == 0:
        raise InputError(f"array {name!r} holds {dtype.kind!r} values; only numbers and text are read", source=source)
    claimed = math.prod(int(n) for n in shape) * dtype.itemsize
    if claimed != size - header:
        raise InputError(f"array {name!r}: its header claims shape {tuple(shape)} ({claimed} bytes) but the file "
                         f"holds {size - header} bytes of it", source=source)
    return shape, fortran, dtype


_MEMBER_ERRORS = (zipfile.BadZipFile, OSError, EOFError, RuntimeError, NotImplementedError)
"""What opening or reading one member of a zip archive may raise on a damaged or hostile file."""


def _npy_members(zf: zipfile.ZipFile):
    """``(info, name)`` of each array (``NAME.npy``) an NPZ archive holds, in its order."""
    for info in zf.infolist():
        if info.filename.endswith(".npy"):
            yield info, info.filename[:-4]


def _check_rows(zf: zipfile.ZipFile, source: str, max_rows: int | str) -> None:
    """Refuse an NPZ whose array headers claim more than ``max_rows`` rows, reading headers only."""
    if max_rows == DATA_LINES:
        from .limits import limit

        top, why = int(limit("SAMPLES")), "set HLAID_MAX_SAMPLES to raise the limit"
    else:
        top, why = int(max_rows), "more than hlaid reads"
    for info, name in _npy_members(zf):
        try:
            with zf.open(info) as member:
                shape, _, _ = _npy_header(member, name, info.file_size, source)
        except _MEMBER_ERRORS:
            continue  # the reading below says what is wrong with it
        if shape and int(shape[0]) > top:
            raise InputError(f"array {name!r} claims {int(shape[0]):,} samples; a record holds at most {top:,} "
                             f"({why})", source=source)


def load_npz(path: str | os.PathLike, *, not_npz: str = "not an NPZ file (a zip archive of named arrays)",
             max_rows: int | str | None = None) -> dict:
    """The arrays of an NPZ file by name, each checked against its member's size before it is
    allocated (see the module docstring); ``not_npz`` is the message for a file that is no zip.
    ``max_rows`` (a count, or :data:`DATA_LINES`: ``HLAID_MAX_SAMPLES``): the longest first
    dimension of an array, checked from its header before any array is inflated."""
    import numpy as np
    source = str(path)
    with open_input(path) as fh:
        _check_members(fh, source)
        try:
            zf = zipfile.ZipFile(fh)
        except (zipfile.BadZipFile, OSError, ValueError):
            raise InputError(not_npz, source=source) from None
        with zf:
            _inflated_total(zf, source)
            if max_rows is not None:
                _check_rows(zf, source, max_rows)
            out = {}
            for info, name in _npy_members(zf):
                try:
                    with zf.open(info) as member:
                        shape, fortran, dtype = _npy_header(member, name, info.file_size, source)
                        data = member.read()
                except _MEMBER_ERRORS as err:
                    raise InputError(f"array {name!r} cannot be read ({one_line(err, 80)})",
                                     source=source) from None
                a = np.frombuffer(data, dtype=dtype)
                out[name] = a.reshape(shape, order="F" if fortran else "C").copy()
            return out
