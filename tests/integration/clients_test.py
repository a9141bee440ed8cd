"""The example clients against the real server: the Python example (8 environments in one vector environment), the
C++ closed-loop client and the load generator. The Python package itself is tested in rl_env_test.py."""
import json
import os
import subprocess
import sys
import unittest

from server_process import Server

PY_CLIENT_DIR = os.environ["SS_PY_CLIENT_DIR"]


class ClientsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = Server().start()

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()

    def test_python_example_eight_envs(self):
        r = subprocess.run([sys.executable, os.path.join(PY_CLIENT_DIR, "run_parallel_envs.py"), "--target",
                            self.server.target, "--envs", "8", "--steps", "3"], capture_output=True, text=True,
                           timeout=120)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("8 environments", r.stdout)

    def test_cpp_closed_loop(self):
        r = subprocess.run([os.environ["SS_CLOSED_LOOP"], "--target", self.server.target, "--steps", "3"],
                           capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("tick 3", r.stdout)

    def test_cpp_load_generator(self):
        r = subprocess.run([os.environ["SS_LOAD"], "--clients", "4", "--steps", "3", "--target", self.server.target,
                            "--json"], capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        out = json.loads(r.stdout)
        self.assertEqual(set(out), {"clients", "steps", "errors", "steps_per_second", "latency_ms_p50",
                                    "latency_ms_p99"})
        self.assertEqual((out["clients"], out["steps"], out["errors"]), (4, 3, 0))
        self.assertGreater(out["steps_per_second"], 0)
        self.assertLessEqual(out["latency_ms_p50"], out["latency_ms_p99"])


if __name__ == "__main__":
    unittest.main(verbosity=2)
