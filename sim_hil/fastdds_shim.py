"""Lets the robot maker's own SDK (booster-robotics-sdk-python 1.6.3, Fast DDS inside) discover Cyclone DDS
participants: `python -m sim_hil --dds --fastdds-compat`, or `python -m sim_hil.fastdds_shim` beside any
Cyclone process, inside tools/netns.

Why (measured, tests/test_dds_booster_sdk.py and the issue-18 notes in README.md): Cyclone's participant
announcement (SPDP) carries its vendor-specific parameter 0x8007 (ADLINK_PARTICIPANT_VERSION_INFO, 48 bytes).
The SDK's Fast DDS reads 0x8007 as its own PID_NETWORK_CONFIGURATION_SET (4 bytes) without checking the
sender's vendor id and drops the whole announcement, so it never answers Cyclone: Cyclone sees the SDK's
participant, the SDK never sees Cyclone's, and no endpoint ever matches. With 0x8007 removed from Cyclone's
announcement the SDK discovers Cyclone and the topics match as they are (type names, XCDR1 data).

What it does: listens to the domain's SPDP multicast group; remembers each Fast DDS participant's metatraffic
unicast locators; re-sends every Cyclone SPDP it hears, without PID 0x8007, to those locators (at once when
either side appears, then every RESEND_S, so a late SDK still learns of Cyclone before its lease ends).
Only SPDP DATA is touched; nothing is sent outside the namespace's loopback.
"""
from __future__ import annotations

import argparse
import socket
import struct
import threading
import time

from messages import contract

SPDP_GROUP = "239.255.0.1"           # RTPS default SPDP multicast group
SPDP_PORT_BASE, DOMAIN_GAIN = 7400, 250   # RTPS well-known port = PB + DG * domain (d0 = 0)
RTPS_MAGIC = b"RTPS"
VENDOR_CYCLONE, VENDOR_FASTDDS = b"\x01\x10", b"\x01\x0f"
SUBMSG_DATA = 0x15
SPDP_WRITER_ID = bytes.fromhex("000100c2")
PID_SENTINEL, PID_METATRAFFIC_UNICAST = 0x0001, 0x0032
PID_CYCLONE_VERSION_INFO = 0x8007    # the parameter the SDK misreads
PL_CDR_LE = b"\x00\x03"
LOCATOR_KIND_UDPV4 = 1
RESEND_S = 1.0
RECV_TIMEOUT_S = 0.2
MAX_DATAGRAM = 65535


def _submessages(msg: bytes):
    """(kind, flags, body, start, end) of each RTPS submessage after the 20-byte header."""
    off = 20
    while off + 4 <= len(msg):
        kind, flags = msg[off], msg[off + 1]
        length = struct.unpack("<H" if flags & 1 else ">H", msg[off + 2:off + 4])[0]
        end = len(msg) if length == 0 else off + 4 + length
        yield kind, flags, msg[off + 4:end], off, end
        if length == 0:
            return
        off = end


def _spdp_params(body: bytes):
    """(data offset, [(pid, value)]) of an SPDP DATA submessage body in PL_CDR_LE, else (None, []) — also for
    a body too short to be one (a malformed datagram must not end the relay's thread)."""
    if len(body) < 12:
        return None, []
    start = 4 + struct.unpack("<H", body[2:4])[0]     # extraFlags, octetsToInlineQos; little endian (E flag)
    data = body[start:]
    if body[8:12] != SPDP_WRITER_ID or data[:2] != PL_CDR_LE:
        return None, []
    params, p = [], 4
    while p + 4 <= len(data):
        pid, plen = struct.unpack("<HH", data[p:p + 4])
        params.append((pid, data[p + 4:p + 4 + plen]))
        if pid == PID_SENTINEL:
            break
        p += 4 + plen
    return start, params


def strip_cyclone_version_info(msg: bytes) -> bytes | None:
    """A Cyclone SPDP datagram without PID 0x8007, or None if it is not one."""
    if msg[:4] != RTPS_MAGIC or msg[6:8] != VENDOR_CYCLONE:
        return None
    out, found = bytearray(msg[:20]), False
    for kind, flags, body, start, end in _submessages(msg):
        if kind == SUBMSG_DATA and flags & 1:
            data_at, params = _spdp_params(body)
            if data_at is not None:
                found = True
                plist = bytearray(body[data_at:data_at + 4])
                for pid, value in params:
                    if pid != PID_CYCLONE_VERSION_INFO:
                        plist += struct.pack("<HH", pid, len(value)) + value
                body = body[:data_at] + bytes(plist)
                out += bytes([kind, flags]) + struct.pack("<H", len(body)) + body
                continue
        out += msg[start:end]
    return bytes(out) if found else None


def fastdds_metatraffic(msg: bytes) -> list[tuple[str, int]]:
    """The UDPv4 metatraffic unicast locators a Fast DDS SPDP datagram announces."""
    if msg[:4] != RTPS_MAGIC or msg[6:8] != VENDOR_FASTDDS:
        return []
    out = []
    for kind, flags, body, _, _ in _submessages(msg):
        if kind != SUBMSG_DATA or not flags & 1:
            continue
        for pid, value in _spdp_params(body)[1]:
            if pid == PID_METATRAFFIC_UNICAST and len(value) == 24:
                loc_kind, port = struct.unpack("<iI", value[:8])
                if loc_kind == LOCATOR_KIND_UDPV4:
                    out.append((socket.inet_ntoa(value[20:24]), port))
    return out


class FastDdsShim:
    """Runs on a daemon thread until stop()."""

    def __init__(self, domain_id: int = contract.DDS["domain_id"]):
        port = SPDP_PORT_BASE + DOMAIN_GAIN * domain_id
        self.rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.rx.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.rx.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)   # the DDS stacks bind this port too
        self.rx.bind((SPDP_GROUP, port))
        self.rx.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP,
                           socket.inet_aton(SPDP_GROUP) + socket.inet_aton("127.0.0.1"))
        self.rx.settimeout(RECV_TIMEOUT_S)
        self.tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.fastdds: set[tuple[str, int]] = set()
        self.cyclone: dict[bytes, bytes] = {}    # GUID prefix -> newest stripped SPDP
        self.forwarded = 0
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name="fastdds-shim", daemon=True)
        self.thread.start()

    def _send(self, messages, targets) -> None:
        for m in messages:
            for t in targets:
                self.tx.sendto(m, t)
                self.forwarded += 1

    def _run(self) -> None:
        last = time.monotonic()
        while not self._stop.is_set():
            try:
                msg = self.rx.recv(MAX_DATAGRAM)
            except socket.timeout:
                msg = b""
            new_peers = [loc for loc in fastdds_metatraffic(msg) if loc not in self.fastdds]
            if new_peers:
                self.fastdds.update(new_peers)
                self._send(self.cyclone.values(), new_peers)
            stripped = strip_cyclone_version_info(msg) if msg else None
            if stripped is not None:
                self.cyclone[msg[8:20]] = stripped
                self._send([stripped], self.fastdds)
            if time.monotonic() - last > RESEND_S:
                last = time.monotonic()
                self._send(self.cyclone.values(), self.fastdds)

    def stop(self) -> None:
        self._stop.set()
        self.thread.join()
        self.rx.close()
        self.tx.close()


def main(argv: list[str] | None = None) -> None:
    argparse.ArgumentParser(prog="python -m sim_hil.fastdds_shim", description=__doc__.split("\n\n")[0]
                            + " Runs until Ctrl-C.").parse_args(argv)
    shim = FastDdsShim()
    print("fastdds_shim: relaying Cyclone SPDP (without PID 0x8007) to Fast DDS participants; Ctrl-C stops")
    try:
        while True:
            time.sleep(RESEND_S)
    except KeyboardInterrupt:
        shim.stop()


if __name__ == "__main__":
    main()
