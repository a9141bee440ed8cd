"""Starts the real scenestreamer-viewer on a free 127.0.0.1 port, as a subprocess, in front of a test server."""
import atexit
import os
import re
import signal
import subprocess
import tempfile
import time

VIEWER = os.environ["SS_VIEWER"]


class Viewer:
    def __init__(self, target, *flags):
        self.args = [VIEWER, "--port=0", f"--target={target}"] + list(flags)
        fd, self.log_path = tempfile.mkstemp(prefix="ss-viewer-", suffix=".log")
        os.close(fd)
        atexit.register(lambda p=self.log_path: os.path.exists(p) and os.remove(p))
        self.proc = None

    def start(self):
        self.log = open(self.log_path, "w")
        self.proc = subprocess.Popen(self.args, stdout=self.log, stderr=subprocess.STDOUT)
        deadline = time.time() + 60
        while time.time() < deadline:
            m = re.search(r"serving the viewer on (https?)://127.0.0.1:(\d+)/", self.output())
            if m:
                self.url = f"{m.group(1)}://127.0.0.1:{m.group(2)}/"
                return self
            if self.proc.poll() is not None:
                raise RuntimeError(f"viewer exited {self.proc.returncode}:\n{self.output()}")
            time.sleep(0.1)
        raise RuntimeError("viewer did not start in 60 s:\n" + self.output())

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        if self.proc:
            self.log.close()

    def output(self):
        with open(self.log_path) as f:
            return f.read()
