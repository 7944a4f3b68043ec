"""sim_hil/fastdds_shim.py's packet surgery, without a network: a Cyclone SPDP loses exactly PID 0x8007 and
stays a well-formed RTPS message; a Fast DDS SPDP gives up its metatraffic unicast locator."""
from __future__ import annotations

import socket
import struct

from sim_hil import fastdds_shim as shim

GUID_PREFIX = bytes(range(12))


def spdp(vendor: bytes, params: list[tuple[int, bytes]]) -> bytes:
    plist = shim.PL_CDR_LE + b"\x00\x00"
    for pid, value in params + [(shim.PID_SENTINEL, b"")]:
        plist += struct.pack("<HH", pid, len(value)) + value
    # DATA body: extraFlags, octetsToInlineQos = 16, readerId, writerId, sequence number, then the payload
    body = b"\x00\x00" + struct.pack("<H", 16) + bytes(4) + shim.SPDP_WRITER_ID + struct.pack("<iI", 0, 1) + plist
    header = b"RTPS\x02\x01" + vendor + GUID_PREFIX
    info_ts = bytes([0x09, 0x01]) + struct.pack("<H", 8) + bytes(8)
    return header + info_ts + bytes([shim.SUBMSG_DATA, 0x05]) + struct.pack("<H", len(body)) + body


def locator(ip: str, port: int) -> bytes:
    return struct.pack("<iI", shim.LOCATOR_KIND_UDPV4, port) + bytes(12) + socket.inet_aton(ip)


def test_cyclone_announcement_loses_only_its_version_info():
    domain = (0x000F, bytes(4))
    meta = (shim.PID_METATRAFFIC_UNICAST, locator("127.0.0.1", 7412))
    msg = spdp(shim.VENDOR_CYCLONE, [domain, (shim.PID_CYCLONE_VERSION_INFO, bytes(48)), meta, (0x8019, bytes(4))])
    out = shim.strip_cyclone_version_info(msg)
    assert out is not None and len(out) == len(msg) - 52
    kinds = [(k, body) for k, _, body, _, _ in shim._submessages(out)]
    assert [k for k, _ in kinds] == [0x09, shim.SUBMSG_DATA]
    _, params = shim._spdp_params(kinds[1][1])
    assert [pid for pid, _ in params] == [0x000F, shim.PID_METATRAFFIC_UNICAST, 0x8019, shim.PID_SENTINEL]


def test_only_cyclone_announcements_are_rewritten_and_fastdds_locators_are_read():
    meta = (shim.PID_METATRAFFIC_UNICAST, locator("127.0.0.1", 7410))
    fast = spdp(shim.VENDOR_FASTDDS, [(0x8007, bytes(4)), meta])
    assert shim.strip_cyclone_version_info(fast) is None
    assert shim.strip_cyclone_version_info(b"not rtps") is None
    assert shim.fastdds_metatraffic(fast) == [("127.0.0.1", 7410)]
    assert shim.fastdds_metatraffic(spdp(shim.VENDOR_CYCLONE, [meta])) == []


def test_short_or_cut_datagrams_are_left_alone_without_an_exception():
    meta = (shim.PID_METATRAFFIC_UNICAST, locator("127.0.0.1", 7412))
    whole = spdp(shim.VENDOR_CYCLONE, [meta])
    short_data = whole[:20] + bytes([shim.SUBMSG_DATA, 0x05]) + struct.pack("<H", 2) + b"\x00\x00"
    for msg in (short_data, whole[:-3]):
        shim.strip_cyclone_version_info(msg)          # no struct.error
        shim.fastdds_metatraffic(msg)
    assert shim.strip_cyclone_version_info(short_data) is None
