"""Requests a hostile or careless client sends the real server binary on 127.0.0.1: a scenario far above the limits
is refused before it is built (the server's peak memory barely moves), a CloseSession stops a long StepScene of the
session, bad InjectAgent radii and sessions with no agent or an uncontrolled SDC are refused naming why, the health
port serves health alone, and a tokens file others may read is warned about."""
import os
import re
import shutil
import struct
import tempfile
import threading
import time
import unittest

import grpc

from scenestreamer.v1 import simulator_pb2 as pb
from server_process import Server, ServerTestCase, error_of

C = grpc.StatusCode


def varint(n):
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        out.append(b | (0x80 if n else 0))
        if not n:
            return bytes(out)


def field(number, wire_type, payload):
    """One protobuf field: its tag, then a varint (wire type 0) or a length-delimited payload (2)."""
    tag = varint(number << 3 | wire_type)
    return tag + (varint(payload) if wire_type == 0 else varint(len(payload)) + payload)


def womd_scenario(tracks, frames=91, current=10, lane_points=40):
    """Serialized waymo.open_dataset.Scenario bytes, made by hand: `tracks` is a list of (id, type, states), each
    state None (invalid) or (x, y, heading, speed); one straight lane along the x axis is the map."""
    out = field(5, 2, b"hand-made")
    out += field(1, 2, b"".join(struct.pack("<d", 0.1 * i) for i in range(frames)))  # timestamps_seconds, packed
    out += field(10, 0, current)
    point = lambda x: b"\x09" + struct.pack("<d", x) + b"\x11" + struct.pack("<d", 0.0) + b"\x19" + struct.pack("<d", 0.0)
    lane = field(2, 0, 2) + b"".join(field(8, 2, point(2.0 * i)) for i in range(lane_points))
    out += field(8, 2, field(1, 0, 1) + field(3, 2, lane))
    for track_id, track_type, states in tracks:
        t = field(1, 0, track_id) + field(2, 0, track_type)
        for s in states:
            if s is None:
                t += field(3, 2, field(11, 0, 0))  # valid: false
            else:
                x, y, h, v = s
                t += field(3, 2, b"\x11" + struct.pack("<d", x) + b"\x19" + struct.pack("<d", y) + b"\x21" +
                           struct.pack("<d", 0.0) + b"\x2d" + struct.pack("<f", 4.5) + b"\x35" + struct.pack("<f", 2.0)
                           + b"\x3d" + struct.pack("<f", 1.5) + b"\x45" + struct.pack("<f", h) + b"\x4d" +
                           struct.pack("<f", v) + b"\x55" + struct.pack("<f", 0.0) + field(11, 0, 1))
        out += field(2, 2, t)
    return out


def driving(x0, frames=91):
    return [(x0 + 0.5 * i, 0.0, 0.0, 5.0) for i in range(frames)]


def peak_rss_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        return int(re.search(r"VmHWM:\s+(\d+) kB", f.read()).group(1)) / 1024


class RequestsTest(ServerTestCase):
    server_flags = ("--health_port=0",)

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.name = cls.server.stub.ListScenarios(pb.ListScenariosRequest()).scenarios[0].name

    def test_a_scenario_far_above_the_limits_is_refused_before_it_is_built(self):
        # Once 100,000 tracks of invalid states (36 MB) were refused only after 2.1 s and RSS 80 MB -> 1.57 GB.
        one = field(2, 2, field(1, 0, 7) + field(2, 0, 1) + field(3, 2, field(11, 0, 0)) * 91)
        big = womd_scenario([]) + one * 100_000
        self.assertGreater(len(big), 35 << 20)
        pid = self.server.proc.pid
        before = peak_rss_mb(pid)
        t0 = time.time()
        code, msg = error_of(self.server.stub.CreateSession, pb.CreateSessionRequest(womd_scenario=big), timeout=120)
        took = time.time() - t0
        after = peak_rss_mb(pid)
        print(f"100,000 tracks ({len(big) >> 20} MB): {code} in {took:.2f} s, peak RSS {before:.0f} -> {after:.0f} MB",
              flush=True)
        self.assertEqual(code, C.RESOURCE_EXHAUSTED, msg)
        self.assertIn("100000 tracks", msg)
        self.assertIn("1024", msg)
        # The request itself is 36 MB and gRPC holds it while the handler runs: allow a few copies, not 40 of them.
        self.assertLess(after - before, 200, "the refused scenario was built before its limits were checked")

    def test_close_stops_a_long_step_of_the_session(self):
        # Once CloseSession let a StepScene of 1000 ticks compute to its end and return OK.
        sid = self.server.stub.CreateSession(pb.CreateSessionRequest(scenario_name=self.name,
                                                                     model_drives_sdc=True)).session_id
        result = {}

        def long_step():
            result["code"], result["msg"] = error_of(self.server.stub.StepScene,
                                                     pb.StepSceneRequest(session_id=sid, num_ticks=1000), timeout=300)

        t = threading.Thread(target=long_step)
        t.start()
        deadline = time.time() + 60
        while self.server.stub.GetSession(pb.GetSessionRequest(session_id=sid)).info.tick < 2:
            self.assertLess(time.time(), deadline)
            time.sleep(0.01)
        self.server.stub.CloseSession(pb.CloseSessionRequest(session_id=sid))
        closed_at = time.time()
        t.join()
        print(f"the step returned {result['code']} {time.time() - closed_at:.3f} s after the close", flush=True)
        self.assertIn(result["code"], (C.ABORTED, C.CANCELLED), result)
        self.assertIn("closed", result["msg"])

    def test_inject_refuses_a_radius_that_is_not_a_distance(self):
        sid = self.server.stub.CreateSession(pb.CreateSessionRequest(scenario_name=self.name)).session_id
        for radius in (-5.0, 1e308):
            req = pb.InjectAgentRequest(session_id=sid, count=1, near_radius=radius)
            req.near.x, req.near.y = 0.0, 0.0
            code, msg = error_of(self.server.stub.InjectAgent, req)
            self.assertEqual(code, C.INVALID_ARGUMENT, f"near_radius {radius}: {msg}")
            self.assertIn("near_radius", msg)
        self.server.stub.CloseSession(pb.CloseSessionRequest(session_id=sid))

    def test_a_session_with_no_agent_or_an_uncontrolled_sdc_is_refused(self):
        # A scenario the hand-made encoder gets right is accepted: the SDC (track 0) is controlled.
        good = womd_scenario([(1, 1, driving(0.0)), (2, 1, driving(20.0))]) + field(6, 0, 0)
        c = self.server.stub.CreateSession(pb.CreateSessionRequest(womd_scenario=good))
        self.assertEqual([a.id for a in c.initial.agents if a.controlled], [1])
        self.server.stub.CloseSession(pb.CloseSessionRequest(session_id=c.session_id))
        # The SDC is not valid at the current frame: once the session started with no controlled agent, silently.
        no_sdc = womd_scenario([(1, 1, [None] * 91), (2, 1, driving(20.0))]) + field(6, 0, 0)
        code, msg = error_of(self.server.stub.CreateSession, pb.CreateSessionRequest(womd_scenario=no_sdc))
        self.assertEqual(code, C.INVALID_ARGUMENT, msg)
        self.assertIn("SDC", msg)
        self.assertIn("model_drives_sdc", msg)
        # With the model driving it, the same scenario is fine.
        c = self.server.stub.CreateSession(pb.CreateSessionRequest(womd_scenario=no_sdc, model_drives_sdc=True))
        self.server.stub.CloseSession(pb.CloseSessionRequest(session_id=c.session_id))
        # No agent at all at the current frame: once a session of zero agents.
        empty = womd_scenario([(1, 1, [None] * 91)])
        code, msg = error_of(self.server.stub.CreateSession,
                             pb.CreateSessionRequest(womd_scenario=empty, model_drives_sdc=True))
        self.assertEqual(code, C.INVALID_ARGUMENT, msg)
        self.assertIn("no agent", msg)

    def test_the_health_port_serves_health_alone(self):
        port = int(re.search(r"health \(plaintext, no tokens\) on 127.0.0.1:(\d+)", self.server.output()).group(1))
        # ServerReflectionRequest { list_services = 7 }: the main port answers, the health port does not know it.
        def reflect(target):
            channel = grpc.insecure_channel(target)
            try:
                call = channel.stream_stream("/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
                                             request_serializer=lambda b: b, response_deserializer=lambda b: b)
                return error_of(lambda: list(call(iter([field(7, 2, b"")]), timeout=10)))[0]
            finally:
                channel.close()
        self.assertIsNone(reflect(self.server.target))
        self.assertEqual(reflect(f"127.0.0.1:{port}"), C.UNIMPLEMENTED)


class TokensFileTest(unittest.TestCase):
    def test_a_tokens_file_others_may_read_is_warned_about(self):
        d = tempfile.mkdtemp(prefix="ss-it-tokens-")
        try:
            tokens = os.path.join(d, "tokens.txt")
            with open(tokens, "w") as f:
                f.write("alice-token-0123456789 alice\n")
            os.chmod(tokens, 0o644)
            with Server(f"--tokens_file={tokens}", token="alice-token-0123456789") as srv:
                self.assertRegex(srv.output(), rf"tokens file {re.escape(tokens)} is readable by other users")
            os.chmod(tokens, 0o600)
            with Server(f"--tokens_file={tokens}", token="alice-token-0123456789") as srv:
                self.assertNotIn("readable by other users", srv.output())
        finally:
            shutil.rmtree(d, ignore_errors=True)


if __name__ == "__main__":
    unittest.main(verbosity=2)
