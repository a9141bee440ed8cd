"""Security of the real server binary on 127.0.0.1: TLS and mutual TLS with certificates made at test time (openssl
CLI), bearer tokens and tenants, controllers that own their agents, the plaintext health port, the loopback default
bind, and clear refusals of bad flags and tokens files."""
import os
import shutil
import subprocess
import tempfile
import threading
import unittest

import grpc

from scenestreamer.v1 import simulator_pb2 as pb
from scenestreamer.v1 import simulator_pb2_grpc as rpc
from pki import Pki
from server_process import DATA, SERVER, Server, channel_to, error_of, small_model

C = grpc.StatusCode
ALICE, BOB = "alice-token-0123456789", "bob-token-abcdefghijkl"


def first_scenario(stub):
    return stub.ListScenarios(pb.ListScenariosRequest()).scenarios[0].name


def run_to_exit(*flags, timeout=60):
    """Runs the server binary with `flags` until it exits; returns (code, output)."""
    p = subprocess.run([SERVER, "--port=0", "--metrics_port=-1", f"--model={small_model()}", f"--scenario_dir={DATA}",
                        *flags], capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stdout + p.stderr


class TlsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.pki = Pki()

    @classmethod
    def tearDownClass(cls):
        cls.pki.close()

    def test_tls_serves_trusting_clients_only(self):
        p = self.pki
        with Server(f"--tls_cert={p.path('server.pem')}", f"--tls_key={p.path('server.key')}",
                    tls_root=p.read("ca.pem")) as srv:
            self.assertIn("(TLS, no authentication", srv.output())
            sid = srv.stub.CreateSession(pb.CreateSessionRequest(scenario_name=first_scenario(srv.stub))).session_id
            self.assertEqual(srv.stub.StepScene(pb.StepSceneRequest(session_id=sid)).ticks[0].tick, 1)
            # A plaintext client, and a TLS client that trusts another CA, do not get through the handshake.
            for channel in (grpc.insecure_channel(srv.target), channel_to(srv.target, tls_root=p.read("other.pem"))):
                code, _ = error_of(rpc.SimulatorStub(channel).ListScenarios, pb.ListScenariosRequest(), timeout=10)
                self.assertEqual(code, C.UNAVAILABLE)
                channel.close()

    def test_mutual_tls_needs_a_client_certificate_the_ca_signed(self):
        p = self.pki
        with Server(f"--tls_cert={p.path('server.pem')}", f"--tls_key={p.path('server.key')}",
                    f"--tls_client_ca={p.path('ca.pem')}", tls_root=p.read("ca.pem"),
                    client_cert=(p.read("client.pem"), p.read("client.key"))) as srv:
            self.assertIn("(mutual TLS", srv.output())
            self.assertTrue(first_scenario(srv.stub))
            for cert in (None, (p.read("other.pem"), p.read("other.key"))):
                channel = channel_to(srv.target, tls_root=p.read("ca.pem"), client_cert=cert)
                code, _ = error_of(rpc.SimulatorStub(channel).ListScenarios, pb.ListScenariosRequest(), timeout=10)
                self.assertEqual(code, C.UNAVAILABLE, f"client certificate {cert and 'other'}")
                channel.close()

    def test_bad_tls_flags_are_refused_at_startup_naming_the_file(self):
        p = self.pki
        cases = [
            ([f"--tls_cert={p.path('server.pem')}"], "--tls_cert and --tls_key go together"),
            ([f"--tls_cert={p.path('server.pem')}", f"--tls_key={p.path('other.key')}"],
             f"--tls_key {p.path('other.key')} is not the private key of the certificate"),
            ([f"--tls_cert={p.path('nope.pem')}", f"--tls_key={p.path('server.key')}"],
             f"--tls_cert {p.path('nope.pem')}"),
            ([f"--tls_cert={p.path('server.ext')}", f"--tls_key={p.path('server.key')}"], "not a PEM file"),
            ([f"--tls_client_ca={p.path('ca.pem')}"], "--tls_client_ca needs --tls_cert"),
        ]
        for flags, says in cases:
            code, out = run_to_exit(*flags)
            self.assertEqual(code, 1, out)
            self.assertIn(says, out)


class TokensTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp(prefix="ss-it-tokens-")
        cls.tokens = os.path.join(cls.dir, "tokens.txt")
        with open(cls.tokens, "w") as f:
            f.write(f"# token tenant\n{ALICE} alice\n{BOB}\tbob\n")
        cls.server = Server(f"--tokens_file={cls.tokens}", token=ALICE).start()
        cls.bob_channel = channel_to(cls.server.target, token=BOB)
        cls.bob = rpc.SimulatorStub(cls.bob_channel)

    @classmethod
    def tearDownClass(cls):
        cls.bob_channel.close()
        cls.server.stop()
        shutil.rmtree(cls.dir, ignore_errors=True)

    def test_every_call_needs_a_known_token(self):
        srv = self.server
        sid = srv.stub.CreateSession(pb.CreateSessionRequest(scenario_name=first_scenario(srv.stub))).session_id
        for token in (None, "not-a-token-0123456789"):
            channel = channel_to(srv.target, token=token)
            stub = rpc.SimulatorStub(channel)
            calls = [
                (stub.ListScenarios, pb.ListScenariosRequest()),
                (stub.ListSessions, pb.ListSessionsRequest()),
                (stub.CreateSession, pb.CreateSessionRequest(scenario_name="x")),
                (stub.StepScene, pb.StepSceneRequest(session_id=sid)),
                (stub.InjectAgent, pb.InjectAgentRequest(session_id=sid, count=1)),
                (stub.StateForce, pb.StateForceRequest(session_id=sid)),
                (stub.GetSession, pb.GetSessionRequest(session_id=sid)),
                (stub.ForkSession, pb.ForkSessionRequest(session_id=sid)),
                (stub.JoinSession, pb.JoinSessionRequest(session_id=sid, agent_ids=[1])),
                (stub.CloseSession, pb.CloseSessionRequest(session_id=sid)),
                (lambda r, timeout: next(stub.WatchSession(r, timeout=timeout)),
                 pb.WatchSessionRequest(session_id=sid)),
            ]
            for fn, req in calls:
                code, msg = error_of(fn, req, timeout=30)
                self.assertEqual(code, C.UNAUTHENTICATED, f"{type(req).__name__} with token {token}")
                self.assertIn("bearer token" if token is None else "not one of this server's tokens", msg)
            channel.close()
        # Alice's session went through all that untouched.
        self.assertEqual(srv.stub.StepScene(pb.StepSceneRequest(session_id=sid)).ticks[0].tick, 1)
        srv.stub.CloseSession(pb.CloseSessionRequest(session_id=sid))

    def test_another_tenants_session_does_not_exist(self):
        srv, bob = self.server, self.bob
        name = first_scenario(srv.stub)
        sid = srv.stub.CreateSession(pb.CreateSessionRequest(scenario_name=name, session_id="alice-own")).session_id
        srv.stub.StepScene(pb.StepSceneRequest(session_id=sid))
        unknown_code, unknown = error_of(bob.GetSession, pb.GetSessionRequest(session_id="alice-0wn"))
        self.assertEqual(unknown_code, C.NOT_FOUND)
        calls = [
            (bob.GetSession, pb.GetSessionRequest(session_id=sid)),
            (bob.StepScene, pb.StepSceneRequest(session_id=sid)),
            (bob.InjectAgent, pb.InjectAgentRequest(session_id=sid, count=1)),
            (bob.StateForce, pb.StateForceRequest(session_id=sid)),
            (bob.ForkSession, pb.ForkSessionRequest(session_id=sid)),
            (bob.JoinSession, pb.JoinSessionRequest(session_id=sid, agent_ids=[1])),
            (bob.CloseSession, pb.CloseSessionRequest(session_id=sid)),
            (lambda r: next(bob.WatchSession(r, timeout=30)), pb.WatchSessionRequest(session_id=sid)),
        ]
        for fn, req in calls:
            code, msg = error_of(fn, req)
            self.assertEqual(code, C.NOT_FOUND, type(req).__name__)
            # Word for word the answer for an id that never existed ("alice-0wn" has the same length).
            self.assertEqual(msg.replace(sid, "alice-0wn"), unknown, type(req).__name__)
        self.assertNotIn(sid, [s.session_id for s in bob.ListSessions(pb.ListSessionsRequest()).sessions])
        self.assertIn(sid, [s.session_id for s in srv.stub.ListSessions(pb.ListSessionsRequest()).sessions])
        # Alice's session is where she left it: bob's step, inject and close did nothing.
        got = srv.stub.GetSession(pb.GetSessionRequest(session_id=sid))
        self.assertEqual(got.info.tick, 1)
        self.assertEqual(srv.stub.StepScene(pb.StepSceneRequest(session_id=sid)).ticks[0].tick, 2)
        # Bob's own sessions are his: alice does not see them either.
        bsid = bob.CreateSession(pb.CreateSessionRequest(scenario_name=name)).session_id
        self.assertEqual(error_of(srv.stub.GetSession, pb.GetSessionRequest(session_id=bsid))[0], C.NOT_FOUND)
        self.assertEqual([s.session_id for s in bob.ListSessions(pb.ListSessionsRequest()).sessions], [bsid])
        bob.CloseSession(pb.CloseSessionRequest(session_id=bsid))
        srv.stub.CloseSession(pb.CloseSessionRequest(session_id=sid))

    def test_a_malformed_tokens_file_is_refused_naming_file_and_line(self):
        bad = os.path.join(self.dir, "bad.txt")
        with open(bad, "w") as f:
            f.write(f"{ALICE} alice\n\n{BOB} bob extra-field\n")
        code, out = run_to_exit(f"--tokens_file={bad}")
        self.assertEqual(code, 1, out)
        self.assertIn(f"tokens file {bad} line 3: expected `TOKEN TENANT`", out)
        code, out = run_to_exit(f"--tokens_file={os.path.join(self.dir, 'missing.txt')}")
        self.assertEqual(code, 1, out)
        self.assertIn("tokens file", out)


def health_check(target, service=""):
    """grpc.health.v1.Health/Check by hand (Debian's python3-grpcio ships no health stubs): the serving status."""
    channel = grpc.insecure_channel(target)
    try:
        # HealthCheckRequest { string service = 1; } / HealthCheckResponse { ServingStatus status = 1; }
        req = (b"\x0a" + bytes([len(service)]) + service.encode()) if service else b""
        check = channel.unary_unary("/grpc.health.v1.Health/Check", request_serializer=lambda b: b,
                                    response_deserializer=lambda b: b)
        resp = check(req, timeout=10)
        return resp[1] if len(resp) >= 2 and resp[0] == 0x08 else 0
    finally:
        channel.close()


class HealthAndBindTest(unittest.TestCase):
    def test_health_needs_no_token_and_has_its_own_plaintext_port(self):
        pki = Pki()
        d = tempfile.mkdtemp(prefix="ss-it-tokens-")
        try:
            tokens = os.path.join(d, "tokens.txt")
            with open(tokens, "w") as f:
                f.write(f"{ALICE} alice\n")
            with Server(f"--tokens_file={tokens}", "--health_port=0", f"--tls_cert={pki.path('server.pem')}",
                        f"--tls_key={pki.path('server.key')}", tls_root=pki.read("ca.pem")) as srv:
                import re
                port = int(re.search(r"health \(plaintext, no tokens\) on 127.0.0.1:(\d+)", srv.output()).group(1))
                self.assertEqual(health_check(f"127.0.0.1:{port}"), 1)  # SERVING, no TLS, no token
                # The main port's health service needs TLS but no token.
                channel = channel_to(srv.target, tls_root=pki.read("ca.pem"))
                check = channel.unary_unary("/grpc.health.v1.Health/Check", request_serializer=lambda b: b,
                                            response_deserializer=lambda b: b)
                self.assertEqual(check(b"", timeout=10), b"\x08\x01")
                channel.close()
                # The health port serves nothing else.
                stub = rpc.SimulatorStub(grpc.insecure_channel(f"127.0.0.1:{port}"))
                self.assertEqual(error_of(stub.ListScenarios, pb.ListScenariosRequest(), timeout=10)[0],
                                 C.UNIMPLEMENTED)
        finally:
            pki.close()
            shutil.rmtree(d, ignore_errors=True)

    def test_a_bare_server_binds_loopback_only(self):
        log = tempfile.NamedTemporaryFile(prefix="ss-it-bare-", suffix=".log", delete=False)
        p = subprocess.Popen([SERVER, "--port=0", "--metrics_port=-1", f"--model={small_model()}",
                              f"--scenario_dir={DATA}"], stdout=log, stderr=subprocess.STDOUT)
        try:
            import re
            import time
            deadline = time.time() + 60
            m = None
            while m is None and time.time() < deadline and p.poll() is None:
                time.sleep(0.1)
                with open(log.name) as f:
                    m = re.search(r"serving scenestreamer.v1.Simulator on (\S+):(\d+)", f.read())
            self.assertIsNotNone(m, "the server did not start")
            self.assertEqual(m.group(1), "127.0.0.1")
            # The kernel agrees: the listening sockets of that port are bound to 127.0.0.1 (gRPC opens an IPv6 socket
            # for the IPv4-mapped ::ffff:127.0.0.1), not to every interface.
            port_hex = "%04X" % int(m.group(2))
            listening = []
            for table in ("/proc/net/tcp", "/proc/net/tcp6"):
                with open(table) as f:
                    rows = [line.split() for line in f.readlines()[1:]]
                listening += [r[1].split(":")[0] for r in rows if r[1].endswith(":" + port_hex) and r[3] == "0A"]
            self.assertTrue(listening, "no listening socket found")
            loopback = {"0100007F", "0000000000000000FFFF00000100007F"}
            self.assertEqual(set(listening) - loopback, set(), f"bound beyond loopback: {listening}")
        finally:
            p.terminate()
            p.wait(timeout=60)
            os.remove(log.name)


class ControllersTest(unittest.TestCase):
    """Two clients share a session with two controlled agents; each joins as the controller of one."""

    def test_only_an_agents_controller_sends_its_poses(self):
        snapshots = tempfile.mkdtemp(prefix="ss-it-snap-")
        self.addCleanup(shutil.rmtree, snapshots, True)
        with Server(snapshot_dir=snapshots) as srv:
            stub = srv.stub
            name = first_scenario(stub)
            probe = stub.CreateSession(pb.CreateSessionRequest(scenario_name=name))
            two = [a.id for a in probe.initial.agents if a.type == pb.AGENT_TYPE_VEHICLE][:2]
            stub.CloseSession(pb.CloseSessionRequest(session_id=probe.session_id))
            c = stub.CreateSession(pb.CreateSessionRequest(scenario_name=name, controlled_agent_ids=two,
                                                           tick_deadline_ms=30000))
            sid = c.session_id
            agents = {a.id: a for a in c.initial.agents}

            def pose(aid):
                s = agents[aid].state
                return pb.ControlledPose(agent_id=aid, x=s.x + 0.5 * s.vx, y=s.y + 0.5 * s.vy, heading=s.heading)

            a = stub.JoinSession(pb.JoinSessionRequest(session_id=sid, agent_ids=[two[0]]))
            b = stub.JoinSession(pb.JoinSessionRequest(session_id=sid, agent_ids=[two[1]]))
            self.assertEqual(list(a.agent_ids), [two[0]])
            self.assertNotEqual(a.controller_credential, b.controller_credential)
            code, msg = error_of(stub.JoinSession, pb.JoinSessionRequest(session_id=sid, agent_ids=[two[0]]))
            self.assertEqual(code, C.ALREADY_EXISTS)
            # Client A moving B's agent (the reported attack), with its own credential or none: refused, clearly.
            for cred in (a.controller_credential, ""):
                code, msg = error_of(stub.StepScene, pb.StepSceneRequest(session_id=sid, poses=[pose(two[1])],
                                                                         controller_credential=cred))
                self.assertEqual(code, C.PERMISSION_DENIED)
                self.assertIn(f"agent {two[1]} of session '{sid}' has a controller", msg)
            forced = pb.ForcedAgent(agent_id=two[1], state=agents[two[1]].state)
            code, msg = error_of(stub.StateForce, pb.StateForceRequest(session_id=sid, agents=[forced],
                                                                       controller_credential=a.controller_credential))
            self.assertEqual(code, C.PERMISSION_DENIED)
            code, msg = error_of(stub.StepScene, pb.StepSceneRequest(session_id=sid, controller_credential="forged"))
            self.assertEqual(code, C.PERMISSION_DENIED)
            self.assertIn("controller_credential is not one", msg)
            # B's own pose is still accepted (once it was refused after A had sent one for it), and the tick
            # advances with both controllers' poses.
            out = {}

            def send(key, cred, aid):
                out[key] = stub.StepScene(pb.StepSceneRequest(session_id=sid, poses=[pose(aid)],
                                                              controller_credential=cred), timeout=60)

            t = threading.Thread(target=send, args=("b", b.controller_credential, two[1]))
            t.start()
            send("a", a.controller_credential, two[0])
            t.join()
            self.assertEqual(out["a"].ticks[0].tick, 1)
            self.assertEqual(out["b"].ticks[0].tick, 1)
            # A fork has no controllers (its creator drives it).
            f = stub.ForkSession(pb.ForkSessionRequest(session_id=sid)).session_id
            j = stub.JoinSession(pb.JoinSessionRequest(session_id=f, agent_ids=two))
            self.assertEqual(sorted(j.agent_ids), sorted(two))
            self.assertEqual(srv.terminate(), 0)
        # The claims are part of the session's snapshot: after a restart they still hold.
        with Server(snapshot_dir=snapshots) as srv:
            code, msg = error_of(srv.stub.StepScene, pb.StepSceneRequest(session_id=sid, poses=[pose(two[0])]))
            self.assertEqual(code, C.PERMISSION_DENIED, msg)
            again = srv.stub.JoinSession(pb.JoinSessionRequest(session_id=sid, agent_ids=[two[0]],
                                                               controller_credential=a.controller_credential))
            self.assertEqual(list(again.agent_ids), [two[0]])


class PythonClientTest(unittest.TestCase):
    """The RL package's connect() and environments with a token and a TLS root certificate."""

    def test_the_package_connects_with_a_token_and_a_tls_root(self):
        import numpy as np

        from scenestreamer import SceneStreamerEnv
        from scenestreamer.client import connect
        pki = Pki()
        self.addCleanup(pki.close)
        tokens = pki.path("tokens.txt")
        with open(tokens, "w") as f:
            f.write(f"{ALICE} alice\n")
        with Server(f"--tls_cert={pki.path('server.pem')}", f"--tls_key={pki.path('server.key')}",
                    f"--tokens_file={tokens}", tls_root=pki.read("ca.pem"), token=ALICE) as srv:
            for root in (pki.path("ca.pem"), pki.read("ca.pem")):  # a path or the PEM bytes
                channel, stub = connect(srv.target, token=ALICE, tls_root=root, route=True)
                self.assertTrue(stub.ListScenarios(pb.ListScenariosRequest(), timeout=30).scenarios)
                channel.close()
            for token, root, code in ((None, pki.path("ca.pem"), C.UNAUTHENTICATED), (ALICE, None, C.UNAVAILABLE)):
                channel, stub = connect(srv.target, token=token, tls_root=root)
                self.assertEqual(error_of(stub.ListScenarios, pb.ListScenariosRequest(), timeout=10)[0], code)
                channel.close()
            env = SceneStreamerEnv(srv.target, max_steps=2, token=ALICE, tls_root=pki.path("ca.pem"))
            obs, info = env.reset(seed=1)
            _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
            self.assertEqual(info["tick"], 1)
            env.close()
        # Bad arguments are refused before any connection, naming what is wrong.
        with self.assertRaisesRegex(ValueError, "tls_root '/nonexistent/ca.pem': cannot read it"):
            connect("127.0.0.1:1", tls_root="/nonexistent/ca.pem")
        with self.assertRaisesRegex(ValueError, "hold no PEM certificate"):
            connect("127.0.0.1:1", tls_root=b"not a certificate")
        for token in ("", "two words", 42):
            with self.assertRaisesRegex(ValueError, "token: a non-empty string"):
                connect("127.0.0.1:1", token=token)


if __name__ == "__main__":
    unittest.main(verbosity=2)
