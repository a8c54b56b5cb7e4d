"""The address of a dask scheduler (``hlaid fleet --scheduler``): checked, then probed, before dask.

An address is ``tcp://HOST:PORT`` (``HOST:PORT`` alone means tcp) or ``tls://HOST:PORT``, the host
a name, an IPv4 address or a bracketed IPv6 address. Anything else (``garbage``, ``tcp://[::1``,
``http://``, ``file://``, ``inproc://x``) is refused at once with one line, before the config is
read. Before dask connects, :func:`probe` opens the TCP connection itself with a timeout and reads
the 8-byte length that a dask scheduler sends first: a server that answers with anything else
(an SSH or HTTP banner, whose first bytes dask would read as a length of exabytes and try to
allocate) is refused, as is one that answers nothing within the timeout.
"""

from __future__ import annotations

import ipaddress
import re
import socket
import struct

from ..errors import InputError

SCHEMES = ("tcp", "tls")
"""Transports of a remote scheduler hlaid connects to."""

CONNECT_TIMEOUT_S = 10.0
"""How long the TCP connection and the scheduler's first bytes may take."""

_HOST = re.compile(r"(?=.{1,253}\Z)[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?(?:\.[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}"
                   r"[A-Za-z0-9])?)*\.?")
_GREETING_MAX = 1 << 20  # a scheduler's handshake is a few hundred bytes


def _bad(address: str, why: str) -> InputError:
    shown = address if len(address) <= 80 else address[:77] + "..."
    return InputError(f"--scheduler {shown!r}: {why}; expected tcp://HOST:PORT or tls://HOST:PORT "
                      "(e.g. tcp://10.0.0.5:8786)")


def parse_address(address: str) -> tuple[str, str, int]:
    """``(scheme, host, port)`` of a scheduler address, or an :class:`InputError` saying what is wrong."""
    text = address.strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    if scheme not in SCHEMES:
        raise _bad(address, f"transport {scheme!r} is not supported")
    if rest.startswith("["):
        host, close, tail = rest[1:].partition("]")
        if not close or not tail.startswith(":"):
            raise _bad(address, "an IPv6 host must be written [ADDRESS]:PORT")
        try:
            ipaddress.IPv6Address(host)
        except ValueError:
            raise _bad(address, "the host is not an IPv6 address") from None
        port_text = tail[1:]
    else:
        host, colon, port_text = rest.rpartition(":")
        if not colon or not host:
            raise _bad(address, "no HOST:PORT")
        if not _HOST.fullmatch(host):
            raise _bad(address, "the host is not a host name or an IP address")
    if not (port_text.isascii() and port_text.isdigit()) or not 1 <= int(port_text) <= 65535:
        raise _bad(address, "the port must be a number in 1..65535")
    return scheme, host, int(port_text)


def probe(address: str, timeout: float | None = None) -> None:
    """Connect to the scheduler at ``address`` and read its first 8 bytes, within ``timeout``; an
    :class:`InputError` (one line) when nothing listens there, nothing answers, or what answers is
    not a dask scheduler. A ``tls://`` scheduler (whose TLS handshake comes first) is only
    connected to, and needs dask's TLS settings (:func:`check_tls`). Other transports (the
    ``inproc://`` address of a cluster in this process) are left to dask."""
    scheme = address.strip().partition("://")[0] if "://" in address else "tcp"
    if scheme not in SCHEMES:
        return
    _, host, port = parse_address(address)
    timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
    sock = _connect(address, host, port, timeout)
    if scheme == "tls":
        sock.close()
        check_tls(address)
        return
    with sock:
        head = b""
        try:
            while len(head) < 8:
                chunk = sock.recv(8 - len(head))
                if not chunk:
                    break
                head += chunk
        except TimeoutError:
            raise InputError(f"--scheduler {address}: it sent nothing within {timeout:g} s; a dask scheduler "
                             "greets first: is this the scheduler's address and port?") from None
        except OSError as err:
            raise InputError(f"--scheduler {address}: the connection failed ({err.strerror or type(err).__name__})"
                             ) from None
    if len(head) < 8:
        raise InputError(f"--scheduler {address}: it closed the connection; is this the scheduler's address and port?")
    (size,) = struct.unpack("Q", head)  # dask's frame length, native byte order as dask writes it
    if not 8 <= size <= _GREETING_MAX:
        raise InputError(f"--scheduler {address}: what answers there is not a dask scheduler (its first bytes are "
                         "no dask greeting); is this the scheduler's address and port?")


TLS_SETTINGS = ("distributed.comm.tls.ca-file", "distributed.comm.tls.client.cert")
"""dask settings a ``tls://`` connection needs (the certificate authority and the client's
certificate; ``distributed.comm.tls.client.key`` too where the key is a file of its own)."""


def check_tls(address: str) -> None:
    """Refuse a ``tls://`` scheduler when dask's configuration (its YAML files or
    ``DASK_DISTRIBUTED__COMM__TLS__*`` variables) gives no TLS certificates to connect with."""
    import dask.config  # light: dask's configuration only

    missing = [k for k in TLS_SETTINGS if not dask.config.get(k, None)]
    if missing:
        raise InputError(f"--scheduler {address}: a tls:// scheduler needs dask's TLS settings, and "
                         f"{' and '.join(missing)} {'is' if len(missing) == 1 else 'are'} not set (dask's config "
                         "files or DASK_DISTRIBUTED__COMM__TLS__CA_FILE, ..._CLIENT__CERT, ..._CLIENT__KEY); or use "
                         "tcp://")


def _connect(address: str, host: str, port: int, timeout: float) -> socket.socket:
    try:
        return socket.create_connection((host, port), timeout=timeout)
    except socket.gaierror:
        raise InputError(f"--scheduler {address}: host {host!r} is not known") from None
    except TimeoutError:
        raise InputError(f"--scheduler {address}: no answer within {timeout:g} s") from None
    except OSError as err:
        raise InputError(f"--scheduler {address}: cannot connect ({err.strerror or type(err).__name__})") from None


__all__ = ["parse_address", "probe", "check_tls", "SCHEMES", "CONNECT_TIMEOUT_S", "TLS_SETTINGS"]
