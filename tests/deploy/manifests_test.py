"""deploy/: the Kubernetes manifests, the compose file and the router configurations agree with each other and with
the server (names, ports, flags, the session store), pass yamllint, build with kustomize, and the routers' own checkers
accept them."""
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
        cls.haproxy_k8s = read("router", "haproxy-k8s.cfg")

    def test_yamllint(self):
        files = [os.path.join(DEPLOY, "k8s", n) for n in sorted(os.listdir(os.path.join(DEPLOY, "k8s")))]
        files += [os.path.join(DEPLOY, "compose.yaml"), os.path.join(DEPLOY, "kustomization.yaml")]
        r = subprocess.run(["yamllint", "-f", "parsable", "-d", YAMLLINT] + files, capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)

    def test_every_kind_is_there(self):
        self.assertEqual(sorted(self.k8s), [
            ("Deployment", "scenestreamer-router"), ("HorizontalPodAutoscaler", "scenestreamer"),
            ("NetworkPolicy", "scenestreamer-store"), ("PodDisruptionBudget", "scenestreamer"),
            ("Service", "scenestreamer"), ("Service", "scenestreamer-router"), ("Service", "scenestreamer-store"),
            ("StatefulSet", "scenestreamer"), ("StatefulSet", "scenestreamer-store")])
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
        self.assertEqual(cm["data"]["haproxy.cfg"], self.haproxy_k8s)
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
        self.assertEqual(r.stdout.count("(dry run)"), 10, r.stdout)

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

    def test_the_replicas_share_the_session_store(self):
        store = self.k8s[("Service", "scenestreamer-store")]
        store_sts = self.k8s[("StatefulSet", "scenestreamer-store")]
        redis = store_sts["spec"]["template"]["spec"]["containers"][0]
        port = store["spec"]["ports"][0]["port"]
        self.assertEqual(redis["ports"][0]["containerPort"], port)
        self.assertEqual(store["spec"]["selector"], store_sts["spec"]["template"]["metadata"]["labels"])
        args = self.server["args"]
        self.assertIn(f"--session_store=redis://{store['metadata']['name']}:{port}", args)
        self.assertFalse([a for a in args if a.startswith("--snapshot_dir")], "snapshots go to the store only")
        self.assertNotIn("volumeClaimTemplates", self.sts["spec"])
        # Each replica's lease names its pod.
        self.assertIn("--replica_id=$(POD_NAME)", args)
        env = {e["name"]: e for e in self.server["env"]}
        self.assertEqual(env["POD_NAME"]["valueFrom"]["fieldRef"]["fieldPath"], "metadata.name")
        # Only the replicas reach the store.
        policy = self.k8s[("NetworkPolicy", "scenestreamer-store")]
        self.assertEqual(policy["spec"]["podSelector"], store_sts["spec"]["selector"])
        self.assertEqual(policy["spec"]["ingress"][0]["from"][0]["podSelector"]["matchLabels"],
                         self.sts["spec"]["selector"]["matchLabels"])
        self.assertEqual(policy["spec"]["ingress"][0]["ports"], [{"port": port}])
        # Compose: the same store for every replica, each named by its service.
        compose = docs("compose.yaml")[0]
        self.assertIn("store", compose["services"])
        for i in range(self.sts["spec"]["replicas"]):
            command = compose["services"][f"scenestreamer-{i}"]["command"]
            self.assertIn("--session_store=redis://store:6379", command)
            self.assertIn(f"--replica_id=scenestreamer-{i}", command)

    def test_the_router_follows_what_the_hpa_may_make_and_the_hpa_scales_down(self):
        hpa = self.k8s[("HorizontalPodAutoscaler", "scenestreamer")]
        self.assertNotEqual(hpa["spec"].get("behavior", {}).get("scaleDown", {}).get("selectPolicy"), "Disabled")
        self.assertEqual(hpa["spec"]["minReplicas"], self.sts["spec"]["replicas"])
        names = upstreams(self.haproxy_k8s, r'server (scenestreamer-\d+) "(\S+)"')
        self.assertEqual([n for n, _ in names], [f"scenestreamer-{i}" for i in range(hpa["spec"]["maxReplicas"])])
        for n, address in names:
            self.assertEqual(address, f"{n}.scenestreamer.${{POD_NAMESPACE}}.svc.cluster.local:50051")
        self.assertIn("balance hdr(x-session-id)", self.haproxy_k8s)
        self.assertIn("hash-type consistent", self.haproxy_k8s)
        self.assertIn("resolvers cluster init-addr none", self.haproxy_k8s)
        router = self.k8s[("Deployment", "scenestreamer-router")]["spec"]["template"]["spec"]["containers"][0]
        self.assertIn("/etc/scenestreamer-router/haproxy.cfg", router["command"])
        env = {e["name"]: e for e in router["env"]}
        self.assertEqual(env["POD_NAMESPACE"]["valueFrom"]["fieldRef"]["fieldPath"], "metadata.namespace")
        self.assertEqual(int(re.search(r"bind :(\d+) proto h2", self.haproxy_k8s).group(1)),
                         router["ports"][0]["containerPort"])

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
            # The Kubernetes router as shipped: its names are resolved at run time, not by the check.
            r = subprocess.run(["haproxy", "-c", "-f", os.path.join(DEPLOY, "router", "haproxy-k8s.cfg")],
                               capture_output=True, text=True, env=dict(os.environ, POD_NAMESPACE="default"))
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        finally:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    unittest.main(verbosity=2)
