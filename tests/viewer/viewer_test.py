"""The live viewer in a real browser: the real server and scenestreamer-viewer on 127.0.0.1, the page in headless
Chromium (Debian's, driven by playwright-core: browser.py). What a person would see is read from the page's DOM and
its drawing hooks (window.__viewer), and compared with what the server says over gRPC."""
import json
import os
import subprocess
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "integration"))

from server_process import DATA, TOOL, Server, channel_to, ego_pose, error_of, small_model  # noqa: E402
from scenestreamer.v1 import simulator_pb2 as pb  # noqa: E402
from scenestreamer.v1 import simulator_pb2_grpc as rpc  # noqa: E402

from browser import Browser  # noqa: E402
from pki import Pki  # noqa: E402
from viewer_process import Viewer  # noqa: E402
import synthetic  # noqa: E402

MODES = {pb.MODE_MOTION: "motion", pb.MODE_FULL: "full", pb.MODE_DENSIFY: "densify", pb.MODE_LOG: "log",
         pb.MODE_IDM: "idm"}

# The session table as a person reads it: one list of cell texts per row.
TABLE_ROWS = "[...document.querySelectorAll('#sessions tbody tr')].map(r => [...r.cells].map(c => c.title || c.textContent))"


def rows_of(list_response):
    return sorted([s.session_id, s.scenario_name, MODES[s.mode], str(s.tick), str(s.num_agents),
                   " ".join(str(i) for i in s.controlled_agent_ids) or "none"] for s in list_response.sessions)


class LiveTest(unittest.TestCase):
    """One server, one viewer and one browser for the class; each test closes the sessions it made."""

    @classmethod
    def setUpClass(cls):
        cls.server = Server().start()
        cls.viewer = Viewer(cls.server.target, f"--scenario_dir={DATA}").start()
        cls.browser = Browser()
        cls.names = [s.name for s in cls.server.stub.ListScenarios(pb.ListScenariosRequest()).scenarios]

    @classmethod
    def tearDownClass(cls):
        cls.browser.close()
        cls.viewer.stop()
        cls.server.stop()

    def setUp(self):
        self.sessions = []

    def tearDown(self):
        for sid in self.sessions:
            error_of(self.server.stub.CloseSession, pb.CloseSessionRequest(session_id=sid))

    def create(self, **kw):
        r = self.server.stub.CreateSession(pb.CreateSessionRequest(**kw))
        self.sessions.append(r.session_id)
        return r

    def test_page_loads_with_no_error(self):
        page = self.browser.open(self.viewer.url)
        page.wait("window.__viewer && window.__viewer.framesDrawn >= 1")
        self.assertEqual(page.eval("document.title"), "SceneStreamer viewer")
        self.assertEqual(page.eval("window.__viewer.renderer"), "canvas2d")
        self.assertEqual(page.eval("window.__viewer.error()"), "")
        self.assertIn("pick a live session", page.eval("document.getElementById('status').textContent"))
        problems = [m for m in page.console() if m.startswith(("error", "pageerror"))]
        self.assertEqual(problems, [])

    def test_session_list_equals_list_sessions(self):
        self.create(scenario_name=self.names[0])
        self.create(scenario_name=self.names[-1], mode=pb.MODE_LOG, seed=3)
        self.create(scenario_name=self.names[0], mode=pb.MODE_FULL, model_drives_sdc=True, seed=5)
        expected = rows_of(self.server.stub.ListSessions(pb.ListSessionsRequest()))
        self.assertEqual(len(expected), 3)
        page = self.browser.open(self.viewer.url)
        page.wait(f"document.querySelectorAll('#sessions tbody tr').length === {len(expected)}")
        self.assertEqual(sorted(page.eval(TABLE_ROWS)), expected)
        # The model-driven session lists no controller; the others name their SDC.
        self.assertIn("none", [r[5] for r in expected])

    def test_agents_drawn_equal_the_ticks_and_a_frame_arrives_per_tick(self):
        r = self.create(scenario_name=self.names[0], seed=11)
        page = self.browser.open(f"{self.viewer.url}#watch={r.session_id}")
        # The stream begins with the current tick, drawn at once.
        page.wait("window.__viewer.ticksDrawn.includes(0)")
        self.assertEqual(page.eval("window.__viewer.agentsPerTick[0]"), len(r.initial.agents))
        # The map arrives beside the ticks, by feature type.
        page.wait("document.getElementById('status').textContent.includes('tick 0')")
        ticks = {0: r.initial}
        tick = r.initial
        for _ in range(6):
            pose = ego_pose(tick)
            tick = self.server.stub.StepScene(pb.StepSceneRequest(session_id=r.session_id,
                                                                  poses=[pose] if pose else [])).ticks[-1]
            ticks[tick.tick] = tick
            page.wait(f"window.__viewer.ticksDrawn.includes({tick.tick})")
        self.assertEqual(page.eval("window.__viewer.ticksReceived"), sorted(ticks))
        self.assertEqual(page.eval("window.__viewer.ticksDrawn"), sorted(ticks))
        drawn = page.eval("window.__viewer.agentsPerTick")
        self.assertEqual({int(k): v for k, v in drawn.items()}, {t: len(x.agents) for t, x in ticks.items()})
        self.assertEqual(page.eval("window.__viewer.lastDrawn.tick"), tick.tick)
        self.assertEqual(page.eval("window.__viewer.error()"), "")

    def test_events_flagged_on_the_page_are_the_engines(self):
        """The page's flags for the ego equal StepScene's events for it (the engine's rules, computed by the server),
        over ticks that include an overlap forced with StateForce."""
        r = self.create(scenario_name=self.names[0], seed=14)
        page = self.browser.open(f"{self.viewer.url}#watch={r.session_id}")
        page.wait("window.__viewer.ticksDrawn.includes(0)")
        tick = r.initial
        ego = next(a for a in tick.agents if a.controlled)
        other = next(a for a in tick.agents if not a.controlled)
        seen_overlap = False
        for i in range(4):
            pose = ego_pose(tick)
            if i == 2:  # the other agent onto the ego's next pose
                me = next(a for a in tick.agents if a.controlled).state
                self.server.stub.StateForce(pb.StateForceRequest(session_id=r.session_id, agents=[pb.ForcedAgent(
                    agent_id=other.id, state=pb.AgentState(x=pose.x, y=pose.y, heading=pose.heading, vx=me.vx,
                                                           vy=me.vy, length=me.length, width=me.width,
                                                           height=me.height))]))
            tick = self.server.stub.StepScene(pb.StepSceneRequest(session_id=r.session_id, poses=[pose])).ticks[-1]
            page.wait(f"window.__viewer.ticksDrawn.includes({tick.tick})")
            flags = {int(k): v for k, v in page.eval(f"window.__viewer.flagsPerTick[{tick.tick}]").items()}
            events = next(e for e in tick.events if e.agent_id == ego.id)
            f = flags.get(ego.id, 0)
            self.assertTrue(f & 1, f"tick {tick.tick}: the ego is drawn as controlled")
            self.assertEqual(bool(f & 4), len(events.overlapping) > 0, f"tick {tick.tick}: overlap {flags}")
            self.assertEqual(bool(f & 8), events.off_road, f"tick {tick.tick}: off road")
            self.assertEqual(bool(f & 16), events.ran_red_light, f"tick {tick.tick}: red light")
            for other_id in events.overlapping:
                self.assertTrue(flags.get(other_id, 0) & 4, f"tick {tick.tick}: agent {other_id} overlaps the ego")
            seen_overlap |= len(events.overlapping) > 0
        self.assertTrue(seen_overlap, "the forced overlap did not happen: the test checked no positive")

    def test_pause_holds_the_picture_and_resume_shows_the_latest_tick(self):
        r = self.create(scenario_name=self.names[0], seed=12)
        page = self.browser.open(f"{self.viewer.url}#watch={r.session_id}")
        page.wait("window.__viewer.ticksDrawn.includes(0)")
        page.click("#pause")
        self.server.stub.StepScene(pb.StepSceneRequest(session_id=r.session_id, num_ticks=2))
        page.wait("window.__viewer.ticksReceived.includes(2)")
        self.assertEqual(page.eval("window.__viewer.lastDrawn.tick"), 0)
        page.click("#pause")
        page.wait("window.__viewer.lastDrawn.tick === 2")

    def test_an_unknown_session_shows_an_error(self):
        page = self.browser.open(f"{self.viewer.url}#watch=no-such-session")
        page.wait("window.__viewer.error() !== ''")
        error = page.eval("window.__viewer.error()")
        self.assertIn("NOT_FOUND", error)
        self.assertIn("no-such-session", error)
        self.assertFalse(page.eval("document.getElementById('error').hidden"))

    def test_a_closed_session_says_so(self):
        r = self.create(scenario_name=self.names[0], seed=13)
        page = self.browser.open(f"{self.viewer.url}#watch={r.session_id}")
        page.wait("window.__viewer.ticksDrawn.includes(0)")
        self.server.stub.CloseSession(pb.CloseSessionRequest(session_id=r.session_id))
        page.wait("document.getElementById('status').textContent.includes('closed')")
        # A redraw after the end (the map's answer arriving after it, a pan, a resize) still says so: such a redraw
        # used to write the last tick's label over it.
        self.assertTrue(page.eval("window.dispatchEvent(new Event('resize'))"))
        self.assertIn("closed", page.eval("document.getElementById('status').textContent"))

    def test_the_map_of_an_unknown_session_is_refused_over_http(self):
        page = self.browser.open(self.viewer.url)
        answer = page.eval("fetch('/api/map?session=nope').then(async r => [r.status, await r.json()])")
        self.assertEqual(answer[0], 404)
        self.assertIn("NOT_FOUND", answer[1]["error"])
        answer = page.eval("fetch('/api/map').then(async r => [r.status, await r.json()])")
        self.assertEqual(answer, [400, {"code": "", "error": "/api/map needs ?session=ID"}])


class RolloutFileTest(unittest.TestCase):
    """Offline: files opened in the page, decoded by the gateway with the engine's readers."""

    @classmethod
    def setUpClass(cls):
        cls.server = Server().start()
        cls.viewer = Viewer(cls.server.target, f"--scenario_dir={DATA}").start()
        cls.browser = Browser()
        cls.dir = tempfile.mkdtemp(prefix="ss-viewer-files-")

    @classmethod
    def tearDownClass(cls):
        cls.browser.close()
        cls.viewer.stop()
        cls.server.stop()
        subprocess.run(["rm", "-rf", cls.dir], check=False)

    def test_a_scenario_json_opens_and_scrubs(self):
        agents = 40
        path = os.path.join(self.dir, "synthetic.json")
        with open(path, "w") as f:
            json.dump(synthetic.scenario(agents, 60), f)
        page = self.browser.open(self.viewer.url)
        page.files("#file", [path])
        page.wait("window.__viewer.mode() === 'file'")
        self.assertEqual(page.eval("window.__viewer.groups()"),
                         [{"id": "synthetic-viewer", "rollouts": 1, "frames": synthetic.FRAMES}])
        # It opens at the scenario's current frame (10 for a JSON scenario).
        self.assertEqual(page.eval("window.__viewer.frame()"), 10)
        for frame in (0, 5, 10, 33, 70, 90):
            # Scrub as a person does: move the range input.
            page.eval(f"(() => {{ const s = document.getElementById('scrub'); s.value = '{frame}';"
                      " s.dispatchEvent(new Event('input')); })()")
            page.wait(f"window.__viewer.lastDrawn.tick === {frame}")
            self.assertEqual(page.eval("window.__viewer.lastDrawn.agents"), synthetic.expected_agents(agents, frame),
                             f"frame {frame}")
        self.assertEqual(page.eval("window.__viewer.error()"), "")

    def test_simulated_rollouts_open_as_k_rollouts_with_the_logged_future(self):
        source = os.path.join(DATA, sorted(os.listdir(DATA))[0])
        outs = []
        for k in range(2):
            out = os.path.join(self.dir, f"rollout{k}.tfrecord")
            subprocess.run([TOOL, "simulate", "--scenario", source, "--model", small_model(), "--steps", "4",
                            "--seed", "1", "--rollout", str(k), "--out", out], check=True, capture_output=True)
            outs.append(out)
        page = self.browser.open(self.viewer.url)
        page.files("#file", outs)
        page.wait("window.__viewer.mode() === 'file' && window.__viewer.groups()[0].rollouts === 2", 60000)
        groups = page.eval("window.__viewer.groups()")
        self.assertEqual(len(groups), 1)
        report = json.loads(subprocess.run([TOOL, "inspect", outs[0], "--json"], check=True, capture_output=True,
                                           text=True).stdout)
        self.assertEqual(groups[0]["frames"], report["frames"])
        self.assertEqual(page.eval("document.getElementById('rollout').options.length"), 3)  # 1, 2, all overlaid
        page.eval("window.__viewer.setFrame(20)")
        page.wait("window.__viewer.lastDrawn.tick === 20")
        self.assertGreater(page.eval("window.__viewer.lastDrawn.agents"), 0)
        # The logged future: the gateway found the source scenario by id in its --scenario_dir.
        self.assertGreater(page.eval("window.__viewer.lastDrawn.ghosts"), 0)
        page.eval("window.__viewer.setFrame(5)")
        page.wait("window.__viewer.lastDrawn.tick === 5")
        self.assertEqual(page.eval("window.__viewer.lastDrawn.ghosts"), 0)  # no ghost over the logged past
        page.eval("(() => { const s = document.getElementById('rollout'); s.value = 'all';"
                  " s.dispatchEvent(new Event('change')); })()")
        page.wait("window.__viewer.lastDrawn.overlays === 1")

    def test_a_bad_file_shows_what_was_wrong(self):
        path = os.path.join(self.dir, "broken.json")
        with open(path, "w") as f:
            f.write('{"objects": [')
        page = self.browser.open(self.viewer.url)
        page.files("#file", [path])
        page.wait("window.__viewer.error() !== ''")
        error = page.eval("window.__viewer.error()")
        self.assertIn("broken.json", error)
        self.assertIn("JSON", error)
        self.assertNotIn("ss-viewer-", error)  # the gateway's temporary name is not the user's


class TokenTest(unittest.TestCase):
    """With --tokens_file the page's token picks the tenant; a bad token is an error on the page."""

    GOOD = "viewer-test-token-alice-0123456789"
    OTHER = "viewer-test-token-bob-0123456789ab"

    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp(prefix="ss-viewer-tokens-")
        tokens = os.path.join(cls.dir, "tokens.txt")
        with open(tokens, "w") as f:
            f.write(f"{cls.GOOD} alice\n{cls.OTHER} bob\n")
        cls.server = Server(f"--tokens_file={tokens}", token=cls.GOOD).start()
        cls.viewer = Viewer(cls.server.target, f"--scenario_dir={DATA}").start()
        cls.browser = Browser()
        names = [s.name for s in cls.server.stub.ListScenarios(pb.ListScenariosRequest()).scenarios]
        cls.alice = cls.server.stub.CreateSession(pb.CreateSessionRequest(scenario_name=names[0])).session_id
        bob = rpc.SimulatorStub(channel_to(cls.server.target, token=cls.OTHER))
        cls.bob = bob.CreateSession(pb.CreateSessionRequest(scenario_name=names[0])).session_id

    @classmethod
    def tearDownClass(cls):
        cls.browser.close()
        cls.viewer.stop()
        cls.server.stop()
        subprocess.run(["rm", "-rf", cls.dir], check=False)

    def connect(self, token, hash_=""):
        page = self.browser.open(self.viewer.url + hash_)
        page.fill("#token", token)
        page.click("#connect")
        return page

    def test_a_bad_token_shows_an_error(self):
        page = self.connect("not-a-token-of-this-server-000")
        page.wait("window.__viewer.error().includes(\"not one of this server's tokens\")")
        self.assertIn("UNAUTHENTICATED", page.eval("window.__viewer.error()"))
        self.assertEqual(page.eval(TABLE_ROWS), [])

    def test_no_token_shows_that_the_server_needs_one(self):
        page = self.browser.open(self.viewer.url)
        page.wait("window.__viewer.error().includes('requires a bearer token')")

    def test_a_malformed_token_is_named(self):
        page = self.connect("has spaces in it")
        page.wait("window.__viewer.error() !== ''")
        self.assertIn("Authorization header", page.eval("window.__viewer.error()"))

    def test_the_list_is_the_tenants_own(self):
        page = self.connect(self.GOOD)
        page.wait(f"document.querySelectorAll('#sessions tbody tr').length === 1")
        self.assertEqual(sorted(page.eval(TABLE_ROWS)),
                         rows_of(self.server.stub.ListSessions(pb.ListSessionsRequest())))
        self.assertEqual(page.eval(TABLE_ROWS)[0][0], self.alice)

    def test_another_tenants_session_is_not_found_and_ones_own_is_watched(self):
        page = self.connect(self.GOOD, f"#watch={self.bob}")
        page.wait("window.__viewer.error().includes('NOT_FOUND')")
        page.eval(f"location.hash = 'watch={self.alice}'")
        page.wait("window.__viewer.ticksDrawn.length >= 1")


class TlsTest(unittest.TestCase):
    """TLS on both sides: the viewer checks the server's certificate (--tls_root) and serves HTTPS and WSS."""

    @classmethod
    def setUpClass(cls):
        cls.pki = Pki()
        cls.server = Server(f"--tls_cert={cls.pki.path('server.pem')}", f"--tls_key={cls.pki.path('server.key')}",
                            tls_root=cls.pki.read("ca.pem")).start()
        cls.viewer = Viewer(cls.server.target, f"--scenario_dir={DATA}", f"--tls_root={cls.pki.path('ca.pem')}",
                            f"--tls_cert={cls.pki.path('server.pem')}", f"--tls_key={cls.pki.path('server.key')}").start()
        cls.browser = Browser()

    @classmethod
    def tearDownClass(cls):
        cls.browser.close()
        cls.viewer.stop()
        cls.server.stop()
        cls.pki.close()

    def test_https_page_lists_and_watches_over_tls(self):
        self.assertTrue(self.viewer.url.startswith("https://"), self.viewer.url)
        names = [s.name for s in self.server.stub.ListScenarios(pb.ListScenariosRequest()).scenarios]
        r = self.server.stub.CreateSession(pb.CreateSessionRequest(scenario_name=names[0]))
        self.addCleanup(error_of, self.server.stub.CloseSession, pb.CloseSessionRequest(session_id=r.session_id))
        page = self.browser.open(f"{self.viewer.url}#watch={r.session_id}")
        page.wait("document.querySelectorAll('#sessions tbody tr').length === 1")
        page.wait("window.__viewer.ticksDrawn.includes(0)")
        self.assertEqual(page.eval("location.protocol"), "https:")
        self.assertEqual(page.eval("window.__viewer.agentsPerTick[0]"), len(r.initial.agents))

    def test_a_plaintext_viewer_in_front_of_a_tls_server_says_it_cannot_reach_it(self):
        plain = Viewer(self.server.target, f"--scenario_dir={DATA}").start()
        try:
            page = self.browser.open(plain.url)
            page.wait("window.__viewer.error().includes('UNAVAILABLE')")
            self.assertIn(self.server.target, page.eval("window.__viewer.error()"))
        finally:
            plain.stop()


class CommandLineTest(unittest.TestCase):
    """Bad flags stop the viewer at start-up with what was wrong."""

    def run_viewer(self, *flags):
        from viewer_process import VIEWER
        return subprocess.run([VIEWER, "--port=0", *flags], capture_output=True, text=True, timeout=60)

    def test_bad_flags_are_named(self):
        d = tempfile.mkdtemp(prefix="ss-viewer-cli-")
        self.addCleanup(subprocess.run, ["rm", "-rf", d], check=False)
        cases = [
            (["--port=70000"], "--port 70000 is not in 0..65535"),
            (["--threads=1"], "--threads must be in 2..1024"),
            ([f"--scenario_dir={d}/missing"], f"--scenario_dir: "),
            ([f"--web_dir={d}"], f"--web_dir {d} holds no index.html"),
            (["--tls_cert=x.pem"], "--tls_cert and --tls_key go together"),
            (["--tls_root=/nonexistent/ca.pem"], "--tls_root /nonexistent/ca.pem: cannot read it"),
            (["--tls_server_name=x"], "--tls_client_cert and --tls_server_name need --tls_root"),
        ]
        for flags, message in cases:
            r = self.run_viewer(f"--scenario_dir={DATA}", *flags)
            self.assertEqual(r.returncode, 1, (flags, r.stderr))
            self.assertIn(message, r.stderr + r.stdout, flags)

    def test_help_lists_the_flags(self):
        r = self.run_viewer("--help")
        self.assertEqual(r.returncode, 0, r.stderr)
        for flag in ("--target", "--tls_root", "--tls_cert", "--scenario_dir", "--web_dir"):
            self.assertIn(flag, r.stdout)


if __name__ == "__main__":
    unittest.main()
