"""Tests of rdea_lab.emulator.framing: commands and binary blocks over a socket pair."""

import socket
import threading
import time

import numpy as np
import pytest

from rdea_lab.emulator.framing import CommandReader, ConnectionClosed, FramingError, decode_block, encode_block

from .helpers import block


@pytest.fixture
def pair():
    a, b = socket.socketpair()
    yield a, CommandReader(b, block_timeout=0.3)
    a.close()
    b.close()


def test_encode_block():
    assert encode_block([]) == b"#10"
    assert encode_block([1.0]) == b"#18" + np.array([1.0], "<f8").tobytes()
    values = np.arange(125.0)
    assert encode_block(values)[:6] == b"#41000"
    np.testing.assert_array_equal(decode_block(encode_block(values)[6:]), values)


def test_commands_split_across_reads(pair):
    client, reader = pair
    values = np.array([1.0, 1.25, np.pi])
    data = b"*IDN?\nTRAJ:STR " + block(values) + b"\nSTAT?\r\n"
    got = []

    def slow_sender():
        for i in range(len(data)):  # one byte per send: every split point
            client.sendall(data[i:i + 1])
            time.sleep(0.0005)

    sender = threading.Thread(target=slow_sender)
    sender.start()
    for _ in range(3):
        got.append(reader.read_command())
    sender.join()
    assert got[0] == ("*IDN?", None)
    assert got[1][0] == "TRAJ:STR "
    np.testing.assert_array_equal(decode_block(got[1][1]), values)
    assert got[2] == ("STAT?", None)


def test_newline_bytes_inside_a_block(pair):
    client, reader = pair
    values = np.frombuffer(b"\n" * 16, "<f8")  # payload made of newlines
    client.sendall(b"TRAJ:VOLT " + block(values) + b"\n*IDN?\n")
    text, payload = reader.read_command()
    assert payload == b"\n" * 16
    assert reader.read_command() == ("*IDN?", None)


def test_block_longer_than_its_header_then_in_step_again(pair):
    client, reader = pair
    client.sendall(b"TRAJ:STR #216" + b"\x00" * 24 + b"\n")
    with pytest.raises(FramingError, match="longer than its header"):
        reader.read_command()
    client.sendall(b"*IDN?\n")
    assert reader.read_command() == ("*IDN?", None)


def test_block_shorter_than_its_header_times_out_and_the_connection_is_given_up(pair):
    """The rest never comes: after block_timeout without a byte the block is refused, fatally (a client
    that sent more later could not be told where its next command starts)."""
    client, reader = pair
    client.sendall(b"TRAJ:STR #224" + b"\x00" * 16 + b"\n")
    with pytest.raises(FramingError, match=r"block data \(header says 24 bytes\): nothing arrived for 0.3 s") as info:
        reader.read_command()
    assert info.value.fatal


def test_a_slow_but_steady_block_is_never_cut_off(pair):
    """At 8 bytes every 0.1 s a 40-byte block and its command take 0.7 s, twice block_timeout: it still
    arrives (the timeout is between two bytes, not over the block)."""
    import threading
    import time

    client, reader = pair
    values = np.arange(5, dtype="<f8")
    data = b"TRAJ:STR " + block(values) + b"\n"

    def trickle():
        for i in range(0, len(data), 8):
            client.sendall(data[i:i + 8])
            time.sleep(0.1)

    t = threading.Thread(target=trickle)
    t.start()
    text, payload = reader.read_command()
    t.join()
    assert text.strip() == "TRAJ:STR" and np.array_equal(np.frombuffer(payload, "<f8"), values)


def test_blocks_held_at_once_are_bounded_over_all_connections():
    from rdea_lab.emulator.framing import ByteBudget

    budget = ByteBudget(1000)
    a, b = socket.socketpair()
    c, d = socket.socketpair()
    try:
        first = CommandReader(b, budget=budget, block_timeout=0.3)
        second = CommandReader(d, budget=budget, block_timeout=0.3)
        a.sendall(b"TRAJ:STR " + block(np.zeros(100)) + b"\n")  # 800 bytes, held until its command is done
        first.read_command()
        c.sendall(b"TRAJ:STR " + block(np.zeros(50)) + b"\n")  # 400 more would pass 1000
        with pytest.raises(FramingError, match="server busy") as info:
            second.read_command()
        assert info.value.fatal
        a.sendall(b"*IDN?\n")
        first.read_command()  # the first block's bytes are given back
        assert budget.used == 0
    finally:
        for s_ in (a, b, c, d):
            s_.close()


@pytest.mark.parametrize("raw, words", [
    (b"TRAJ:STR #x12\n", "not a digit"),
    (b"TRAJ:STR #0abc\n", "indefinite-length"),
    (b"TRAJ:STR #3a8\n", "is not 3 digits"),
    (b"\xff\xfe\n", "not ASCII"),
    (b"A" * 5000 + b"\n", "longer than 4096"),
])
def test_bad_input_is_one_error_and_the_reader_recovers(pair, raw, words):
    client, reader = pair
    client.sendall(raw)
    with pytest.raises(FramingError, match=words):
        reader.read_command()
    client.sendall(b"*IDN?\n")
    assert reader.read_command() == ("*IDN?", None)


def test_oversized_block_is_fatal(pair):
    client, reader = pair
    client.sendall(b"TRAJ:STR #9999999999\n")
    with pytest.raises(FramingError) as info:
        reader.read_command()
    assert info.value.fatal


def test_values_must_be_whole_float64():
    with pytest.raises(FramingError, match="not a whole number of float64"):
        decode_block(b"\x00" * 12)


def test_closed_connection(pair):
    client, reader = pair
    client.sendall(b"*ID")
    client.close()
    with pytest.raises(ConnectionClosed):
        reader.read_command()
