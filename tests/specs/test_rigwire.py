"""Tests of rdea_lab.specs.rigwire: the rig protocol declared once, against its document and references."""

import re
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from rdea_lab.specs import rigwire as wire

DOC = Path(__file__).resolve().parents[2] / "docs" / "rig-protocol.md"


def test_the_table_declares_the_commands_of_the_document():
    table = [line for line in DOC.read_text(encoding="utf-8").splitlines() if line.startswith("| `")]
    documented = {code.split()[0] for line in table for code in re.findall(r"`([^`]+)`", line.split("|")[1])}
    assert documented == set(wire.COMMANDS)


def test_who_may_send_what():
    before_auth = {h for h, c in wire.COMMANDS.items() if c.access == wire.BEFORE_AUTH}
    assert before_auth == {"ABOR", "SYST:AUTH?", "SYST:AUTH"}
    settings = {h for h, c in wire.COMMANDS.items() if c.setting}
    assert settings <= {h for h, c in wire.COMMANDS.items() if c.access == wire.CONTROLLER}
    assert all(not c.setting for c in wire.COMMANDS.values() if c.query)


def test_auth_response_is_hmac_sha256():
    # RFC 4231, test case 2 (key "Jefe")
    assert wire.auth_response("Jefe", "what do ya want for nothing?") == (
        "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843")
    assert wire.is_nonce(wire.new_nonce())


def test_armed_checksum_is_the_crc32_of_the_float64_sequence():
    x, v = [1.0, 1.1, 1.2], [0.0, 100.0, 200.0]
    data = struct.pack("<12d", 100.0, 3000.0, 1.6, 50.0, 8e7, 48e-6, *x, *v)
    assert wire.armed_checksum(100.0, [3000.0, 1.6, 50.0, 8e7], 48e-6, x, v) == f"{zlib.crc32(data):08x}"


def test_blocks_round_trip():
    values = np.array([1.0, -2.5, np.pi])
    block = wire.encode_block(values)
    assert block[:4] == b"#224" and wire.encode_block([]) == b"#10"
    np.testing.assert_array_equal(wire.decode_block(block[4:]), values)
    with pytest.raises(wire.FramingError, match="not a whole number of float64"):
        wire.decode_block(b"\0" * 7)


@pytest.mark.parametrize("text, code, message", [
    ("", wire.MISSING_PARAMETER, r"missing parameter: sample rate \[Hz\]"),
    ("fast", wire.DATA_TYPE_ERROR, r"'fast' is not a plain decimal number"),
    ("0.5", wire.DATA_OUT_OF_RANGE, r"sample rate 0.5 Hz is outside 1 Hz to 100000 Hz"),
])
def test_a_number_is_parsed_as_declared(text, code, message):
    command = wire.COMMANDS["CONF:RATE"]
    with pytest.raises(wire.RigError, match=message) as info:
        command.arg.parse(command.header, text, None)
    assert info.value.code == code
    assert command.arg.parse(command.header, "250", None) == 250.0
    assert command.line(250.0) == "CONF:RATE 250.0" and command.usage == "CONF:RATE <Hz>"


def test_replies_read_back():
    assert wire.read_status(wire.status_reply("ABORTED", 3, 2, 'said "no"')) == ("ABORTED", 3, 2, "said 'no'")
    assert wire.error_message(wire.error_reply(-222, "too high")) == "too high"
    assert wire.line("CONF:MEAS", ("force", "current")) == "CONF:MEAS FORC,CUR"
