"""The page the gateway serves (viewer/web/dist, committed) is what viewer/web/src builds to: a change to the sources
without `npm run build` in viewer/web fails here, naming the files that differ."""
import filecmp
import os
import subprocess
import tempfile
import unittest

WEB = os.path.join(os.environ["SS_SOURCE_DIR"], "viewer", "web")


def files(root):
    return sorted(os.path.relpath(os.path.join(d, f), root) for d, _, fs in os.walk(root) for f in fs)


class BundleTest(unittest.TestCase):
    def test_dist_is_the_build_of_the_sources(self):
        self.assertTrue(os.path.isdir(os.path.join(WEB, "node_modules", "vite")),
                        "viewer/web/node_modules has no vite: run deploy/install-deps.sh (npm ci in viewer/web)")
        with tempfile.TemporaryDirectory(prefix="ss-viewer-dist-") as out:
            r = subprocess.run(["npx", "--no-install", "tsc", "--noEmit"], cwd=WEB, capture_output=True, text=True)
            self.assertEqual(r.returncode, 0, f"TypeScript errors:\n{r.stdout}{r.stderr}")
            r = subprocess.run(["npx", "--no-install", "vite", "build", "--outDir", out, "--emptyOutDir"], cwd=WEB,
                               capture_output=True, text=True)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            dist = os.path.join(WEB, "dist")
            self.assertEqual(files(out), files(dist), "viewer/web/dist is not the build of viewer/web/src: run "
                             "`npm run build` in viewer/web and commit dist/")
            differ = [f for f in files(out) if not filecmp.cmp(os.path.join(out, f), os.path.join(dist, f), False)]
            self.assertEqual(differ, [], "viewer/web/dist differs from the build of viewer/web/src: run `npm run "
                             "build` in viewer/web and commit dist/")


if __name__ == "__main__":
    unittest.main()
