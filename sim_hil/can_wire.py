"""python-can endpoints of the simulator's buses, for the users who want the frames as python-can sees them
(`--can-interface virtual | udp_multicast`, `--can-log`): one (host, motor) pair of endpoints per bus."""
from __future__ import annotations

import os
import queue

import can
from can.interfaces.virtual import VirtualBus, channels_lock

UDP_GROUP = "239.74.163.2"      # IPv4: the IPv6 default group delivers nothing inside the namespace
UDP_BASE_PORT = 31113           # bus b on port 31113 + b: Linux delivers a group's datagrams to every
                                # socket bound to the port, whatever group it joined, so ports separate buses.
                                # Below Linux's ephemeral range (32768-60999): any unbound UDP sender (LCM,
                                # DDS) may be handed a port there, and a bus could then not bind its own


class SimVirtualBus(VirtualBus):
    """python-can's `virtual` interface (same channel registry: any `can.Bus(interface="virtual",
    channel=...)` in this process sees the traffic, e.g. for a logger or an injector), without the
    per-receiver deepcopy and blocking queue calls of `VirtualBus.send`: at 23k frames per sim second those
    dominated the simulator's profile. A frame is never mutated after it is sent, so sharing it is safe."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        # A lock-free C queue in place of queue.Queue; it still accepts put(msg, block, timeout) from
        # stock VirtualBus senders on the same channel.
        with channels_lock:
            slot = self.channel.index(self.queue)
            self.queue = queue.SimpleQueue()
            self.channel[slot] = self.queue

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._check_if_open()
        msg.channel = self.channel_id
        msg.is_rx = True                     # as every receiver sees it
        for bus_queue in self.channel:
            if bus_queue is not self.queue or self.receive_own_messages:
                bus_queue.put_nowait(msg)

    def drain(self) -> list[can.Message]:
        """Everything queued, without BusABC.recv's per-frame filtering and debug logging (no filters are
        set on the simulator's own endpoints)."""
        out = []
        try:
            while True:
                out.append(self.queue.get_nowait())
        except queue.Empty:
            return out

    def _recv_internal(self, timeout: float | None):
        try:
            if not timeout:
                return self.queue.get_nowait(), False
            return self.queue.get(block=True, timeout=timeout), False
        except queue.Empty:
            return None, False


def open_pair(interface: str, bus_index: int) -> tuple[can.BusABC, can.BusABC]:
    """(host side, motor side) endpoints of one physical bus."""
    if interface == "virtual":
        channel = f"t1_bus{bus_index}_{os.getpid()}_{id(object())}"
        kw = dict(channel=channel, receive_own_messages=False, preserve_timestamps=True)
        return SimVirtualBus(**kw), SimVirtualBus(**kw)
    if interface == "udp_multicast":
        port = UDP_BASE_PORT + bus_index
        kw = dict(interface="udp_multicast", channel=UDP_GROUP, port=port, hop_limit=0)
        ends: list[can.BusABC] = []
        try:
            while len(ends) < 2:
                ends.append(can.Bus(**kw))
        except can.CanInitializationError as exc:
            for end in ends:
                end.shutdown()
            raise OSError(f"CAN bus {bus_index}: cannot bind UDP port {port} on {UDP_GROUP} ({exc.__cause__ or exc}):"
                          " another program holds it without SO_REUSEADDR") from exc
        return ends[0], ends[1]
    raise ValueError(f"unknown --can-interface '{interface}' (virtual | udp_multicast)")


def drain(end: can.BusABC) -> list[can.Message]:
    if isinstance(end, SimVirtualBus):
        return end.drain()
    out = []
    while (msg := end.recv(0.0)) is not None:
        out.append(msg)
    return out
