"""Framing of the rig command set: ASCII lines, and IEEE 488.2 definite-length blocks.

A command is ASCII text ending in ``\\n``; an array argument is a block
``#<d><n><n bytes>`` (little-endian float64) followed by ``\\n``. The reader
copes with any split of the bytes over ``recv`` calls, and turns every
malformed input into a `FramingError` that the server answers with one
``ERR`` line, after which it is in step with the client again. The blocks'
encoding and `FramingError` are the protocol's (`rdea_lab.specs.rigwire`).
"""

from __future__ import annotations

import socket
import threading
import time

from ..specs.rigwire import (BLOCK_DATA_ERROR, COMMAND_ERROR, INVALID_CHARACTER, TOKEN_REQUIRED,
                              FramingError, decode_block, encode_block)


class ConnectionClosed(Exception):
    """The peer closed the connection (or it was shut down)."""


class ConnectionIdle(ConnectionClosed):
    """Nothing arrived for the reader's idle timeout: the server closes the connection."""


class ByteBudget:
    """Bytes of block payload the server holds at once, over all connections (a total memory bound)."""

    def __init__(self, total: int):
        self.total, self.used = int(total), 0
        self._lock = threading.Lock()

    def take(self, n: int) -> bool:
        with self._lock:
            if self.used + n > self.total:
                return False
            self.used += n
            return True

    def give(self, n: int) -> None:
        with self._lock:
            self.used = max(0, self.used - n)


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
        Seconds a block (and its newline) may go without a byte arriving once
        its header began; then the block is refused and the connection closed
        (a client still sending could not be told where the next command
        starts). A block arriving slowly but steadily is never cut off.
    idle : callable, optional
        ``idle()`` -> seconds to wait for the next command before the
        connection is idle (`ConnectionIdle`), or None to wait for ever.
    budget : ByteBudget, optional
        Shared bound on the block bytes held by all connections at once.
    """

    def __init__(self, sock: socket.socket, *, max_line: int = 4096, max_block: int = 8 * 10_000_000,
                 block_timeout: float = 2.0, idle=None, budget: ByteBudget | None = None,
                 line_timeout: float = 5.0, min_block_rate: float = 1e6):
        self.sock = sock
        self.max_line = max_line
        self.max_block = max_block
        self.block_timeout = block_timeout
        self.line_timeout = line_timeout
        self.min_block_rate = min_block_rate
        self.idle = idle
        self.budget = budget
        self._deadline: float | None = None  # when the command being read must be whole (or None: wait)
        self._block_deadline: float | None = None  # when the block being read must be whole
        self._begun = False  # whether a byte of the command being read has arrived
        self._held = 0  # bytes of the budget this reader holds (until the next command is read)
        self._buf = bytearray()
        self._skip_line = False  # discard input up to the next newline

    # -------------------------------------------------------------- bytes
    def _fill(self, deadline: float | None = None) -> bool:
        """Receive more bytes; False on timeout (only with a `deadline`). Without one, the command's own
        deadline holds (`read_command`: a line whole within `line_timeout` of its first byte, a command
        within ``idle()`` of the last one): past it, `ConnectionIdle`. Deadlines, not timeouts per
        ``recv``: a byte now and then does not keep a connection open."""
        timeout = None
        if deadline is not None:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            self.sock.settimeout(remaining)
        else:
            if self._deadline is not None:
                timeout = self._deadline - time.monotonic()
                if timeout <= 0:
                    raise ConnectionIdle(self._late())
                self.sock.settimeout(timeout)
        try:
            chunk = self.sock.recv(65536)
        except socket.timeout:
            if deadline is None:
                raise ConnectionIdle(self._late()) from None
            return False
        finally:
            if deadline is not None or timeout is not None:
                self.sock.settimeout(None)
        if not chunk:
            raise ConnectionClosed()
        if deadline is None and not self._begun:  # a command has begun: it has line_timeout to be whole
            self._begun = True
            whole_by = time.monotonic() + self.line_timeout
            self._deadline = whole_by if self._deadline is None else min(self._deadline, whole_by)
        self._buf += chunk
        return True

    def _late(self) -> str:
        if self._begun:
            return f"a command not whole {self.line_timeout:g} s after its first byte"
        return "no command in time"

    def _need(self, n: int, what: str) -> None:
        """Wait for ``n`` bytes, as long as they keep coming: at most `block_timeout` between two, and
        all of them before the block's deadline (its header's line deadline, then `min_block_rate`)."""
        while len(self._buf) < n:
            end = self._block_deadline if self._block_deadline is not None else self._deadline
            gap = time.monotonic() + self.block_timeout
            if end is not None and end <= gap:
                if not self._fill(end):
                    got = len(self._buf)
                    self._buf.clear()
                    raise FramingError(BLOCK_DATA_ERROR, f"{what}: not whole in time ({got} bytes; at least "
                                             f"{self.min_block_rate:g} bytes/s); closing the connection",
                                       fatal=True)
                continue
            if not self._fill(gap):
                got = len(self._buf)
                self._buf.clear()
                raise FramingError(BLOCK_DATA_ERROR, f"{what}: nothing arrived for {self.block_timeout:g} s after "
                                                     f"{got} bytes; closing the connection", fatal=True)

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
        if self._held and self.budget is not None:  # the previous block has been handled: give its bytes back
            self.budget.give(self._held)
            self._held = 0
        self._block_deadline = None
        self._begun = bool(self._buf)
        if self._begun:  # the next command's first bytes came with the last one
            self._deadline = time.monotonic() + self.line_timeout
        else:
            idle = self.idle() if self.idle is not None else None
            self._deadline = time.monotonic() + idle if idle is not None else None
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
                try:
                    text = self._text(bytes(self._buf[:hash_]))
                except FramingError:  # consume what is refused: the line, block and all (one ERR per line)
                    self._drop_line(hash_)
                    raise
                return text, self._block(hash_)
            if nl >= 0:
                line = bytes(self._buf[:nl])
                del self._buf[:nl + 1]
                if len(line) > self.max_line:
                    raise FramingError(COMMAND_ERROR, f"command longer than {self.max_line} bytes")
                return self._text(line.rstrip(b"\r")), None
            if len(self._buf) > self.max_line:
                return self._too_long()
            self._fill()

    def _too_long(self):
        self._buf.clear()
        self._skip_line = True
        raise FramingError(COMMAND_ERROR, f"command longer than {self.max_line} bytes")

    @staticmethod
    def _text(raw: bytes) -> str:
        try:
            return raw.decode("ascii")
        except UnicodeDecodeError as exc:
            raise FramingError(INVALID_CHARACTER, f"invalid character: byte 0x{raw[exc.start]:02x} at position "
                                                  f"{exc.start} is not ASCII") from None

    def _block(self, start: int) -> bytes:
        """Parse the block whose ``#`` is at `start`; consume it and its newline."""
        self._need(start + 2, "block header")
        d = chr(self._buf[start + 1])
        if d == "0":
            self._drop_line(start)
            raise FramingError(BLOCK_DATA_ERROR, "indefinite-length block (#0) not accepted; send a definite-length "
                                     "block #<d><n><bytes>")
        if not d.isdigit():
            self._drop_line(start)
            raise FramingError(BLOCK_DATA_ERROR, f"invalid block header: {d!r} after '#' is not a digit 1-9")
        digits = int(d)
        self._need(start + 2 + digits, "block header")
        size_text = bytes(self._buf[start + 2:start + 2 + digits])
        if not size_text.isdigit():
            self._drop_line(start)
            raise FramingError(BLOCK_DATA_ERROR, f"invalid block header: length {size_text!r} is not {digits} digits")
        size = int(size_text)
        if size > self.max_block:
            self._buf.clear()
            if self.max_block == 0:
                raise FramingError(TOKEN_REQUIRED, "blocks only after authentication (SYST:AUTH)", fatal=True)
            raise FramingError(BLOCK_DATA_ERROR, f"block of {size} bytes is larger than the largest accepted "
                                     f"({self.max_block} bytes)", fatal=True)
        if self.budget is not None:
            if not self.budget.take(size):
                self._buf.clear()
                raise FramingError(BLOCK_DATA_ERROR, f"server busy: blocks of other connections already hold "
                                         f"{self.budget.used} of {self.budget.total} bytes; try again", fatal=True)
            self._held = size
        begin = start + 2 + digits
        # the whole block has a deadline too: at least min_block_rate bytes/s on average (besides at most
        # block_timeout between two bytes), so that no connection holds budget by dribbling
        self._block_deadline = time.monotonic() + self.line_timeout + size / self.min_block_rate
        self._need(begin + size, f"block data (header says {size} bytes)")
        self._need(begin + size + 1, "newline after the block")
        end = begin + size
        if self._buf[end:end + 1] == b"\r":
            self._need(end + 2, "newline after the block")
            end += 1
        if self._buf[end:end + 1] != b"\n":
            self._resync()
            raise FramingError(BLOCK_DATA_ERROR,
                               f"block longer than its header says ({size} bytes), or no newline after it")
        payload = bytes(self._buf[begin:begin + size])
        del self._buf[:end + 1]
        return payload

    def _drop_line(self, start: int) -> None:
        del self._buf[:start + 1]
        self._skip_line = True


    def release(self) -> None:
        """Give back the budget this reader holds (its connection ends)."""
        if self._held and self.budget is not None:
            self.budget.give(self._held)
        self._held = 0


__all__ = ["ByteBudget", "CommandReader", "ConnectionClosed", "ConnectionIdle", "FramingError", "decode_block",
           "encode_block"]
