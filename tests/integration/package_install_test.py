"""`pip install` of the package (python/) into a fresh virtual environment that sees Debian's site packages, offline,
then the quick start (client_examples/python/quickstart.py) run by that environment's interpreter against the
real server. The package is copied with proto/ to a temporary directory first, so the build leaves nothing in the
repository."""
import os
import shutil
import subprocess
import tempfile
import unittest

from server_process import Server

PACKAGE = os.environ["SS_PY_PACKAGE_DIR"]
EXAMPLES = os.environ["SS_PY_CLIENT_DIR"]


class PackageInstallTest(unittest.TestCase):
    def test_install_into_a_fresh_venv_and_run_the_quick_start(self):
        work = tempfile.mkdtemp(prefix="ss-pkg-")
        self.addCleanup(shutil.rmtree, work, True)
        shutil.copytree(PACKAGE, os.path.join(work, "python"), ignore=shutil.ignore_patterns("build", "*.egg-info",
                                                                                           "__pycache__"))
        shutil.copytree(os.path.join(PACKAGE, "..", "proto"), os.path.join(work, "proto"))
        venv = os.path.join(work, "venv")
        subprocess.run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", venv], check=True)
        py = os.path.join(venv, "bin", "python")
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # only what the venv has installed
        r = subprocess.run([py, "-m", "pip", "install", "--no-index", "--no-build-isolation", "./python"], cwd=work,
                           env=env, capture_output=True, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        r = subprocess.run([py, "-c", "import scenestreamer, scenestreamer.v1.simulator_pb2_grpc; "
                                      "print(scenestreamer.__file__)"], cwd=work, env=env, capture_output=True,
                           text=True, timeout=60)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertTrue(r.stdout.strip().startswith(venv), r.stdout)
        with Server() as server:
            r = subprocess.run([py, os.path.join(EXAMPLES, "quickstart.py"), server.target], cwd=work, env=env,
                               capture_output=True, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("return ", r.stdout)
        self.assertIn("'lanes': (64, 4)", r.stdout)


if __name__ == "__main__":
    unittest.main(verbosity=2)
