"""The install target (`cmake --install BUILD --prefix P`) and the programs as installed, run from another directory:
the programs land in P/bin, the default model, its card and the sample scenarios in P/share/scenestreamer; the
installed server starts with no flags but a loopback address and free ports, finds its model and scenarios from
where it is installed, and serves them (ListScenarios, gRPC health through the installed probe); the installed
`scenestreamer simulate` and `eval` find the default model the same way. A program copied away from its share/ folder
refuses to start, naming where it looked, even from a directory that holds models/ and data/ (the working directory
is never where defaults come from)."""
import os
import re
import shutil
import signal
import subprocess
import tempfile
import time
import unittest

import grpc

from scenestreamer.v1 import simulator_pb2 as pb
from scenestreamer.v1 import simulator_pb2_grpc as rpc
from server_process import womd_records

BUILD = os.environ["SS_BUILD_DIR"]
SOURCE = os.environ["SS_SOURCE_DIR"]
CMAKE = os.environ.get("SS_CMAKE", "cmake")
SAMPLE = "sumo.tfrecord-00000-of-00001"


def run(args, cwd, timeout=600):
    return subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=timeout)


class InstalledServer:
    """The installed server as a subprocess in `cwd`, on 127.0.0.1 and a free port; its log in a file."""

    def __init__(self, binary, cwd, *flags):
        self.log_path = os.path.join(cwd, "server.log")
        self.log = open(self.log_path, "w")
        self.proc = subprocess.Popen([binary, "--host=127.0.0.1", "--port=0", "--metrics_port=-1", "--threads=2",
                                      *flags], cwd=cwd, stdout=self.log, stderr=subprocess.STDOUT)

    def output(self):
        with open(self.log_path) as f:
            return f.read()

    def wait_serving(self, timeout=120):
        """The port the server logged it serves on; RuntimeError with the log when it exits or never does."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            m = re.search(r"serving scenestreamer.v1.Simulator on 127.0.0.1:(\d+)", self.output())
            if m:
                return int(m.group(1))
            if self.proc.poll() is not None:
                raise RuntimeError(f"the installed server exited {self.proc.returncode}:\n{self.output()}")
            time.sleep(0.1)
        raise RuntimeError(f"the installed server did not serve in {timeout} s:\n{self.output()}")

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            self.proc.wait(timeout=60)
        self.log.close()
        return self.proc.returncode


class InstallTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="ss-install-test-")
        cls.prefix = os.path.join(cls.tmp, "prefix")
        r = run([CMAKE, "--install", BUILD, "--prefix", cls.prefix], cwd=cls.tmp)
        if r.returncode:
            raise RuntimeError(f"cmake --install failed ({r.returncode}):\n{r.stdout}\n{r.stderr}")
        cls.bin = os.path.join(cls.prefix, "bin")
        cls.share = os.path.join(cls.prefix, "share", "scenestreamer")

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def workdir(self):
        """An empty directory outside the repository and the prefix, to run the programs from."""
        d = tempfile.mkdtemp(prefix="cwd-", dir=self.tmp)
        return d

    def test_layout(self):
        for program in ("scenestreamer-server", "scenestreamer-health", "scenestreamer", "scenestreamer-load",
                        "scenestreamer-closed-loop"):
            path = os.path.join(self.bin, program)
            self.assertTrue(os.access(path, os.X_OK), path)
        with open(os.path.join(SOURCE, "models", "default.safetensors"), "rb") as f:
            model = f.read()
        with open(os.path.join(self.share, "models", "default.safetensors"), "rb") as f:
            self.assertEqual(f.read(), model)
        # The model card (docs/model.md) beside the model.
        with open(os.path.join(SOURCE, "docs", "model.md")) as f:
            card = f.read()
        with open(os.path.join(self.share, "models", "model.md")) as f:
            self.assertEqual(f.read(), card)
        self.assertEqual(sorted(os.listdir(os.path.join(self.share, "data"))),
                         sorted(os.listdir(os.path.join(SOURCE, "data"))))
        # Nothing of the development tree: no training checkpoint, no build or test files.
        self.assertNotIn("train-checkpoint.pt", os.listdir(os.path.join(self.share, "models")))
        self.assertEqual(sorted(os.listdir(self.prefix)), ["bin", "share"])

    def test_installed_server_serves_its_bundled_model_and_scenarios(self):
        cwd = self.workdir()
        server = InstalledServer(os.path.join(self.bin, "scenestreamer-server"), cwd)
        try:
            port = server.wait_serving()
            log = server.output()
            self.assertIn(f"model {os.path.join(self.share, 'models', 'default.safetensors')} ", log)
            self.assertNotIn("RANDOM", log)
            n = len(womd_records(os.path.join(self.share, "data", SAMPLE)))
            self.assertIn(f"{n} scenarios from {os.path.join(self.share, 'data')}", log)
            with grpc.insecure_channel(f"127.0.0.1:{port}") as channel:
                stub = rpc.SimulatorStub(channel)
                scenarios = stub.ListScenarios(pb.ListScenariosRequest(), timeout=60).scenarios
                self.assertEqual(len(scenarios), n)
                r = stub.CreateSession(pb.CreateSessionRequest(scenario_name=scenarios[0].name, seed=1), timeout=60)
                tick = stub.StepScene(pb.StepSceneRequest(session_id=r.session_id), timeout=60).ticks[-1]
                self.assertEqual(tick.tick, r.initial.tick + 1)
            health = run([os.path.join(self.bin, "scenestreamer-health"), "--target", f"127.0.0.1:{port}"], cwd,
                         timeout=60)
            self.assertEqual(health.returncode, 0, health.stdout + health.stderr)
            self.assertIn("SERVING", health.stdout + health.stderr)
        finally:
            code = server.stop()
        self.assertEqual(code, 0, server.output())
        self.assertEqual(sorted(os.listdir(cwd)), ["server.log"])  # nothing read or written beside it

    def test_installed_tools_find_the_default_model(self):
        cwd = self.workdir()
        tool = os.path.join(self.bin, "scenestreamer")
        data = os.path.join(self.share, "data", SAMPLE)
        r = run([tool, "simulate", "--scenario", data, "--steps", "3", "--out", "rollout.json"], cwd)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("simulated", r.stdout)
        self.assertGreater(os.path.getsize(os.path.join(cwd, "rollout.json")), 0)
        r = run([tool, "eval", "--data", data, "--rollouts", "1", "--threads", "2", "--json", "eval.json"], cwd)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        with open(os.path.join(cwd, "eval.json")) as f:
            text = f.read()
        model = os.path.join(self.share, "models", "default.safetensors")
        self.assertRegex(text, r'"model": *"' + re.escape(model) + '"')

    def test_a_program_without_its_share_folder_refuses_naming_where_it_looked(self):
        # A directory that holds models/ and data/ like the source tree: the copies must not take them.
        cwd = self.workdir()
        shutil.copytree(os.path.join(self.share, "models"), os.path.join(cwd, "models"))
        shutil.copytree(os.path.join(self.share, "data"), os.path.join(cwd, "data"))
        elsewhere = os.path.join(self.tmp, "elsewhere", "bin")
        os.makedirs(elsewhere, exist_ok=True)
        for program in ("scenestreamer-server", "scenestreamer"):
            shutil.copy2(os.path.join(self.bin, program), elsewhere)
        missing = os.path.join(self.tmp, "elsewhere", "share", "scenestreamer")
        server = InstalledServer(os.path.join(elsewhere, "scenestreamer-server"), cwd)
        code = server.proc.wait(timeout=120)
        server.stop()
        log = server.output()
        self.assertEqual(code, 1, log)
        self.assertIn("cannot start: no --scenario_dir given, and no bundled files for", log)
        self.assertIn(f"no {missing} ", log)
        self.assertIn("--scenario_dir DIR", log)
        r = run([os.path.join(elsewhere, "scenestreamer"), "simulate", "--scenario",
                 os.path.join("data", SAMPLE), "--steps", "1", "--out", "x.json"], cwd)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("no --model given, and no bundled files for", r.stderr)
        self.assertIn(missing, r.stderr)
        self.assertFalse(os.path.exists(os.path.join(cwd, "x.json")))
        # With the flags the same copies run from the same directory.
        r = run([os.path.join(elsewhere, "scenestreamer"), "simulate", "--scenario", os.path.join("data", SAMPLE),
                 "--model", os.path.join("models", "default.safetensors"), "--steps", "1", "--out", "x.json"], cwd)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)


if __name__ == "__main__":
    unittest.main(verbosity=2)
