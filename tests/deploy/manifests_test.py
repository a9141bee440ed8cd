"""deploy/: the Kubernetes manifests, the compose file and both router configurations agree with each other and with
the server (names, ports, flags), pass yamllint, build with kustomize, and the routers' own checkers accept them."""
import os
import re
import shutil
import subprocess
import tempfile
import unittest

import yaml

SOURCE_DIR = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DEPLOY = os.path.join(SOURCE_DIR, "deploy")
YAMLLINT = "{extends: default, rules: {line-length: {max: 120}, document-start: disable}}"


def read(*path):
    with open(os.path.join(DEPLOY, *path)) as f:
        return f.read()


def docs(*path):
    return [d for d in yaml.safe_load_all(read(*path)) if d]


def upstreams(text, pattern):
    return re.findall(pattern, text)


class ManifestsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.k8s = {}
        for name in sorted(os.listdir(os.path.join(DEPLOY, "k8s"))):
            for d in docs("k8s", name):
                cls.k8s[(d["kind"], d["metadata"]["name"])] = d
        cls.sts = cls.k8s[("StatefulSet", "scenestreamer")]
        cls.server = cls.sts["spec"]["template"]["spec"]["containers"][0]
        cls.nginx = read("router", "nginx.conf")
        cls.haproxy = read("router", "haproxy.cfg")

    def test_yamllint(self):
        files = [os.path.join(DEPLOY, "k8s", n) for n in sorted(os.listdir(os.path.join(DEPLOY, "k8s")))]
        files += [os.path.join(DEPLOY, "compose.yaml"), os.path.join(DEPLOY, "kustomization.yaml")]
        r = subprocess.run(["yamllint", "-f", "parsable", "-d", YAMLLINT] + files, capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)

    def test_every_kind_is_there(self):
        self.assertEqual(sorted(self.k8s), [
            ("Deployment", "scenestreamer-router"), ("HorizontalPodAutoscaler", "scenestreamer"),
            ("PodDisruptionBudget", "scenestreamer"), ("Service", "scenestreamer"),
            ("Service", "scenestreamer-router"), ("StatefulSet", "scenestreamer")])
        kustomization = docs("kustomization.yaml")[0]
        self.assertEqual(sorted(kustomization["resources"]),
                         sorted(f"k8s/{n}" for n in os.listdir(os.path.join(DEPLOY, "k8s"))))

    def test_kustomize_builds_the_router_config_from_the_file(self):
        if not shutil.which("kubectl"):
            self.skipTest("kubectl is not installed")
        r = subprocess.run(["kubectl", "kustomize", DEPLOY], capture_output=True, text=True, timeout=60)
        self.assertEqual(r.returncode, 0, r.stderr)
        built = [d for d in yaml.safe_load_all(r.stdout) if d]
        cm = [d for d in built if d["kind"] == "ConfigMap"][0]
        self.assertEqual(cm["data"]["nginx.conf"], self.nginx)
        router = [d for d in built if d["kind"] == "Deployment"][0]
        self.assertEqual(router["spec"]["template"]["spec"]["volumes"][0]["configMap"]["name"], cm["metadata"]["name"])

    def test_kubectl_dry_run(self):
        if not shutil.which("kubectl"):
            self.skipTest("kubectl is not installed")
        r = subprocess.run(["kubectl", "apply", "--dry-run=client", "--validate=false", "-k", DEPLOY],
                           capture_output=True, text=True, timeout=120)
        if r.returncode != 0 and "connection refused" in r.stderr:
            # kubectl maps kinds to resources through an API server's discovery, even for a client dry run.
            self.skipTest("no Kubernetes API server reachable: kubectl's client dry run needs one for discovery")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(r.stdout.count("(dry run)"), 7, r.stdout)

    def test_names_and_ports_agree(self):
        grpc_port = next(p["containerPort"] for p in self.server["ports"] if p["name"] == "grpc")
        self.assertIn(f"--port={grpc_port}", self.server["args"])
        for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
            self.assertEqual(self.server[probe]["grpc"]["port"], grpc_port, probe)
        headless = self.k8s[("Service", "scenestreamer")]
        self.assertEqual(headless["spec"]["clusterIP"], "None")
        self.assertEqual(self.sts["spec"]["serviceName"], "scenestreamer")
        replicas = self.sts["spec"]["replicas"]
        names = [f"scenestreamer-{i}.scenestreamer:{grpc_port}" for i in range(replicas)]
        self.assertEqual(upstreams(self.nginx, r"server (\S+) max_fails"), names)
        self.assertEqual(upstreams(self.haproxy, r"server scenestreamer-\d (\S+)"), names)
        compose = docs("compose.yaml")[0]
        aliases = [compose["services"][f"scenestreamer-{i}"]["networks"]["cluster"]["aliases"][0] + f":{grpc_port}"
                   for i in range(replicas)]
        self.assertEqual(aliases, names)
        listen = int(re.search(r"listen (\d+) http2;", self.nginx).group(1))
        self.assertEqual(int(re.search(r"bind :(\d+) proto h2", self.haproxy).group(1)), listen)
        router = self.k8s[("Service", "scenestreamer-router")]
        self.assertEqual(router["spec"]["ports"][0]["targetPort"], listen)
        self.assertEqual(compose["services"]["router"]["ports"], [f"50051:{listen}"])
        self.assertIn("hash $http_x_session_id consistent;", self.nginx)
        self.assertIn("balance hdr(x-session-id)", self.haproxy)
        self.assertIn("hash-type consistent", self.haproxy)
        # The snapshot volume is where the server writes.
        mount = self.server["volumeMounts"][0]
        self.assertIn(f"--snapshot_dir={mount['mountPath']}", self.server["args"])
        self.assertEqual(self.sts["spec"]["volumeClaimTemplates"][0]["metadata"]["name"], mount["name"])

    def test_server_flags_exist(self):
        server = os.environ.get("SS_SERVER")
        if not server:
            self.skipTest("SS_SERVER not set (run through ctest)")
        helpfull = subprocess.run([server, "--helpfull"], capture_output=True, text=True).stdout
        for arg in self.server["args"]:
            self.assertIn(arg.split("=")[0] + " ", helpfull, arg)

    def test_routers_accept_their_configs(self):
        work = tempfile.mkdtemp(prefix="ss-router-check-")
        try:
            # The replicas' names do not resolve here: loopback addresses stand in, nothing else changes.
            local = lambda t: re.sub(r"scenestreamer-(\d)\.scenestreamer:50051", r"127.0.0.1:5005\1", t)
            conf = os.path.join(work, "nginx.conf")
            with open(conf, "w") as f:
                f.write(local(self.nginx))
            r = subprocess.run(["nginx", "-t", "-p", work + "/", "-c", conf, "-e", "stderr"], capture_output=True,
                               text=True)
            self.assertEqual(r.returncode, 0, r.stderr)
            cfg = os.path.join(work, "haproxy.cfg")
            with open(cfg, "w") as f:
                f.write(local(self.haproxy))
            r = subprocess.run(["haproxy", "-c", "-f", cfg], capture_output=True, text=True)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        finally:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    unittest.main(verbosity=2)
