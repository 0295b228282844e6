"""Framing of the rig command set: ASCII lines, and IEEE 488.2 definite-length blocks.

A command is ASCII text ending in ``\\n``; an array argument is a block
``#<d><n><n bytes>`` (little-endian float64) followed by ``\\n``. The reader
copes with any split of the bytes over ``recv`` calls, and turns every
malformed input into a `FramingError` that the server answers with one
``ERR`` line, after which it is in step with the client again.
"""

from __future__ import annotations

import socket
import time

import numpy as np


class ConnectionClosed(Exception):
    """The peer closed the connection (or it was shut down)."""


class FramingError(Exception):
    """Malformed input; ``code`` and ``message`` make the ``ERR`` reply.

    ``fatal`` means the reader cannot find the next command again (a block
    header announcing more bytes than accepted): the connection is closed.
    """

    def __init__(self, code: int, message: str, fatal: bool = False):
        super().__init__(message)
        self.code, self.message, self.fatal = code, message, fatal


def encode_block(values) -> bytes:
    """Values as a definite-length block of little-endian float64 (``#10`` if empty)."""
    data = np.ascontiguousarray(values, dtype="<f8").tobytes()
    size = str(len(data))
    return f"#{len(size)}{size}".encode("ascii") + data


def decode_block(payload: bytes) -> np.ndarray:
    """The float64 values of a block's payload; FramingError if not whole values."""
    if len(payload) % 8:
        raise FramingError(-161, f"block of {len(payload)} bytes is not a whole number of float64 values (8 bytes each)")
    return np.frombuffer(payload, dtype="<f8").astype(float)


class CommandReader:
    """Reads commands from a connected socket.

    Parameters
    ----------
    sock : socket.socket
        Blocking socket.
    max_line : int
        Longest command text accepted [bytes].
    max_block : int
        Largest block payload accepted [bytes].
    block_timeout : float
        Seconds allowed for the rest of a block (and its newline) to arrive
        once its header was read; then the block is refused.
    """

    def __init__(self, sock: socket.socket, *, max_line: int = 4096, max_block: int = 8 * 10_000_000,
                 block_timeout: float = 2.0):
        self.sock = sock
        self.max_line = max_line
        self.max_block = max_block
        self.block_timeout = block_timeout
        self._buf = bytearray()
        self._skip_line = False  # discard input up to the next newline

    # -------------------------------------------------------------- bytes
    def _fill(self, deadline: float | None = None) -> bool:
        """Receive more bytes; False on timeout (only with a `deadline`)."""
        if deadline is not None:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            self.sock.settimeout(remaining)
        try:
            chunk = self.sock.recv(65536)
        except socket.timeout:
            return False
        finally:
            if deadline is not None:
                self.sock.settimeout(None)
        if not chunk:
            raise ConnectionClosed()
        self._buf += chunk
        return True

    def _need(self, n: int, deadline: float, what: str) -> None:
        while len(self._buf) < n:
            if not self._fill(deadline):
                got = len(self._buf)
                self._resync()
                raise FramingError(-161, f"{what}: only {got} bytes arrived within {self.block_timeout:g} s")

    def _resync(self, quiet: float = 0.1, limit: float = 2.0) -> None:
        """Drop the buffer and whatever arrives until the line is quiet for `quiet` s."""
        self._buf.clear()
        end = time.monotonic() + limit
        while time.monotonic() < end:
            if not self._fill(min(end, time.monotonic() + quiet)):
                break
            self._buf.clear()
        self._buf.clear()

    # ----------------------------------------------------------- commands
    def read_command(self) -> tuple[str, bytes | None]:
        """The next command: its text (up to a block, if any) and the block's payload.

        Raises
        ------
        FramingError
            Too long a line, a bad block header, a block shorter or longer
            than its header says, non-ASCII text.
        ConnectionClosed
        """
        while True:
            if self._skip_line:
                nl = self._buf.find(b"\n")
                if nl < 0:
                    self._buf.clear()
                    self._fill()
                    continue
                del self._buf[:nl + 1]
                self._skip_line = False
            nl = self._buf.find(b"\n")
            hash_ = self._buf.find(b"#", 0, nl if nl >= 0 else len(self._buf))
            if hash_ >= 0:
                if hash_ > self.max_line:
                    return self._too_long()
                text = self._text(bytes(self._buf[:hash_]))
                return text, self._block(hash_)
            if nl >= 0:
                line = bytes(self._buf[:nl])
                del self._buf[:nl + 1]
                if len(line) > self.max_line:
                    raise FramingError(-100, f"command longer than {self.max_line} bytes")
                return self._text(line.rstrip(b"\r")), None
            if len(self._buf) > self.max_line:
                return self._too_long()
            self._fill()

    def _too_long(self):
        self._buf.clear()
        self._skip_line = True
        raise FramingError(-100, f"command longer than {self.max_line} bytes")

    @staticmethod
    def _text(raw: bytes) -> str:
        try:
            return raw.decode("ascii")
        except UnicodeDecodeError as exc:
            raise FramingError(-101, f"invalid character: byte 0x{raw[exc.start]:02x} at position {exc.start} "
                                     "is not ASCII") from None

    def _block(self, start: int) -> bytes:
        """Parse the block whose ``#`` is at `start`; consume it and its newline."""
        deadline = time.monotonic() + self.block_timeout
        self._need(start + 2, deadline, "block header")
        d = chr(self._buf[start + 1])
        if d == "0":
            self._drop_line(start)
            raise FramingError(-161, "indefinite-length block (#0) not accepted; send a definite-length "
                                     "block #<d><n><bytes>")
        if not d.isdigit():
            self._drop_line(start)
            raise FramingError(-161, f"invalid block header: {d!r} after '#' is not a digit 1-9")
        digits = int(d)
        self._need(start + 2 + digits, deadline, "block header")
        size_text = bytes(self._buf[start + 2:start + 2 + digits])
        if not size_text.isdigit():
            self._drop_line(start)
            raise FramingError(-161, f"invalid block header: length {size_text!r} is not {digits} digits")
        size = int(size_text)
        if size > self.max_block:
            self._buf.clear()
            raise FramingError(-161, f"block of {size} bytes is larger than the largest accepted "
                                     f"({self.max_block} bytes)", fatal=True)
        begin = start + 2 + digits
        self._need(begin + size, deadline, f"block data (header says {size} bytes)")
        self._need(begin + size + 1, deadline, "newline after the block")
        end = begin + size
        if self._buf[end:end + 1] == b"\r":
            self._need(end + 2, deadline, "newline after the block")
            end += 1
        if self._buf[end:end + 1] != b"\n":
            self._resync()
            raise FramingError(-161, f"block longer than its header says ({size} bytes), or no newline after it")
        payload = bytes(self._buf[begin:begin + size])
        del self._buf[:end + 1]
        return payload

    def _drop_line(self, start: int) -> None:
        del self._buf[:start + 1]
        self._skip_line = True


__all__ = ["CommandReader", "ConnectionClosed", "FramingError", "decode_block", "encode_block"]
