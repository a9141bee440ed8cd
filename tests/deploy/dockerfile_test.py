"""The Dockerfile builds what `make` builds, the way `make` builds it: packages only through deploy/install-deps.sh
(its build set in the build stage, its runtime set in the image), CMake configured with the Makefile's CMAKE_OPTIONS,
the programs and the bundled files installed by the install target (its server component in the build stage, its
share component in a stage of its own, so a new model leaves the compiled layers cached), and a slim, non-root image
whose health check is the project's own probe. Reads the files; builds nothing (`make image` does, see README)."""
import os
import re
import shlex
import subprocess
import unittest

SOURCE_DIR = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def read(*path):
    with open(os.path.join(SOURCE_DIR, *path)) as f:
        return f.read()


def instructions(dockerfile):
    """(INSTRUCTION, arguments) pairs, continuation lines joined and comments dropped."""
    lines = [l for l in dockerfile.splitlines() if not l.lstrip().startswith("#")]
    text = re.sub(r"\\\n", " ", "\n".join(lines))
    out = []
    for line in text.splitlines():
        if line.strip():
            word, _, rest = line.strip().partition(" ")
            out.append((word.upper(), rest.strip()))
    return out


def stages(dockerfile):
    result, current = [], None
    for ins, args in instructions(dockerfile):
        if ins == "FROM":
            current = (args, [])
            result.append(current)
        elif current:
            current[1].append((ins, args))
    return result


def makefile_variable(name):
    m = re.search(rf"^{name}\s*\??=\s*(.*)$", read("Makefile"), re.M)
    if not m:
        raise AssertionError(f"Makefile has no {name}")
    return m.group(1).split()


class DockerfileTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.stages = stages(read("Dockerfile"))

    def runs(self, stage):
        return [a for i, a in self.stages[stage][1] if i == "RUN"]

    def test_stages_on_debian_bookworm(self):
        self.assertEqual([s[0] for s in self.stages],
                         ["debian:bookworm AS build", "build AS share", "debian:bookworm"])

    def test_packages_come_only_from_install_deps(self):
        sets = re.findall(r"^  (\w+)\) PACKAGES=", read("deploy", "install-deps.sh"), re.M)
        for stage, wanted in ((0, "build"), (2, "runtime")):
            runs = " && ".join(self.runs(stage))
            self.assertRegex(runs, rf"install-deps\.sh {wanted}\b", f"stage {stage}")
            self.assertIn(wanted, sets)
            self.assertNotRegex(runs, r"apt-get install|apt install|dpkg -i|curl|wget", f"stage {stage}")
            # The script the stage runs is the repository's own file, copied in before it runs.
            copies = [a for i, a in self.stages[stage][1] if i == "COPY"]
            self.assertTrue(any(a.startswith("deploy/install-deps.sh ") for a in copies), copies)

    def test_cmake_options_are_the_makefiles(self):
        configure = [r for r in self.runs(0) if "cmake -S" in r]
        self.assertEqual(len(configure), 1)
        words = shlex.split(configure[0].split("&&")[0])
        options = makefile_variable("CMAKE_OPTIONS")
        for opt in options:
            self.assertIn(opt, words, f"the Makefile's CMake option {opt} is missing from the image's build")
        # The only option of its own: the CPU target, portable unless asked (the Makefile's build is native).
        extra = [w for w in words[words.index("build") + 1:] if w not in options]
        self.assertEqual(extra, ["-DSCENESTREAMER_NATIVE=${NATIVE}"])
        self.assertIn(("ARG", "NATIVE=OFF"), self.stages[0][1])
        self.assertRegex(read("Makefile"), r"cmake -S \. -B \$\(BUILD\) \$\(CMAKE_OPTIONS\)")

    def test_installed_binaries_are_built_targets(self):
        build = [r for r in self.runs(0) if "cmake --build" in r][0]
        targets = re.search(r"--target ([\w\- ]+?)(?:&&|$)", build).group(1).split()
        self.assertEqual(sorted(targets), ["scenestreamer-health", "scenestreamer-server"])
        cmake = read("server", "CMakeLists.txt") + read("client_examples", "CMakeLists.txt")
        for t in targets:
            self.assertIn(f"add_executable({t} ", cmake)
        # The install target's server component holds exactly the targets built (a missing one fails the install).
        component = re.findall(r"install\(TARGETS ([\w\- ]+?) RUNTIME DESTINATION bin COMPONENT server\)",
                               read("CMakeLists.txt"))
        self.assertEqual([sorted(c.split()) for c in component], [sorted(targets)])
        self.assertRegex(build, r"DESTDIR=/install cmake --install build --prefix /usr/local --component server")

    def test_bundled_files_come_from_the_install_target(self):
        share = dict()
        for ins, args in self.stages[1][1]:
            share.setdefault(ins, []).append(args)
        self.assertEqual(sorted(share["COPY"]),
                         ["data/ /src/data/", "docs/model.md /src/docs/model.md", "models/ /src/models/"])
        self.assertEqual(share["RUN"], ["DESTDIR=/install cmake --install build --prefix /usr/local --component share"])
        self.assertRegex(read("CMakeLists.txt"), r"install\(FILES models/default.safetensors docs/model.md DESTINATION "
                                                 r"share/scenestreamer/models COMPONENT share\)")
        self.assertRegex(read("CMakeLists.txt"), r"install\(DIRECTORY data/ DESTINATION share/scenestreamer/data "
                                                 r"COMPONENT share\)")
        copies = [a for i, a in self.stages[2][1] if i == "COPY" and a.startswith("--from=")]
        self.assertEqual(copies, ["--from=share /install/usr/local/ /usr/local/"])

    def test_build_stage_copies_sources_only(self):
        # A new model or new scenarios must not invalidate the compiled layers: the build stage copies the folders
        # CMake reads, and every folder the top-level CMakeLists.txt adds is among them.
        copies = [a.split()[0] for i, a in self.stages[0][1] if i == "COPY"]
        self.assertNotIn(".", copies)
        self.assertFalse({"models", "data", "docs"} & set(copies), copies)
        for sub in re.findall(r"add_subdirectory\((\w+)", read("CMakeLists.txt")):
            self.assertIn(sub, copies, f"CMakeLists.txt adds {sub}/, which the build stage does not copy")

    def test_slim_non_root_image_with_its_own_health_probe(self):
        final = dict()
        for ins, args in self.stages[2][1]:
            final.setdefault(ins, []).append(args)
        self.assertEqual(final["USER"], ["scenestreamer"])
        self.assertIn("useradd", " ".join(final["RUN"]))
        health = final["HEALTHCHECK"][0]
        self.assertIn('CMD ["scenestreamer-health", "--target", "127.0.0.1:50051"]', health)
        entry = final["ENTRYPOINT"][0] + " " + final["CMD"][0]
        self.assertIn("scenestreamer-server", entry)
        self.assertIn("--port=50051", entry)
        self.assertIn("--snapshot_dir=/srv/scenestreamer/snapshots", entry)
        # The bundled files only through the install tree (test_bundled_files_come_from_the_install_target).
        self.assertFalse([a for a in final["COPY"] if a.startswith(("data", "models"))], final["COPY"])
        # No build tree, VCS or training checkpoint in the context.
        ignore = read(".dockerignore").split()
        for pattern in ("build", ".git", "models/*", "!models/*.safetensors"):
            self.assertIn(pattern, ignore)

    def test_server_flags_exist(self):
        server = os.environ.get("SS_SERVER")
        if not server:
            self.skipTest("SS_SERVER not set (run through ctest)")
        helpfull = subprocess.run([server, "--helpfull"], capture_output=True, text=True).stdout
        cmd = [a for i, a in self.stages[2][1] if i == "CMD"][-1]
        for flag in re.findall(r'"--(\w+)=', cmd):
            self.assertIn(f"--{flag} ", helpfull)

    def test_runtime_set_holds_the_binaries_libraries(self):
        # The final stage installs only install-deps.sh's runtime set: every shared library the server and the probe
        # load must come from a package of that set or one it depends on (a missing one is found only when the
        # image's server fails to start).
        binaries = [os.environ.get("SS_SERVER"), os.environ.get("SS_HEALTH")]
        if not all(binaries):
            self.skipTest("SS_SERVER and SS_HEALTH not set (run through ctest)")
        runtime = re.search(r'^RUNTIME="([^"]*)"', read("deploy", "install-deps.sh"), re.M).group(1).split()
        closure = subprocess.run(["apt-cache", "depends", "--recurse", "--no-recommends", "--no-suggests",
                                  "--no-conflicts", "--no-breaks", "--no-replaces", "--no-enhances", *runtime],
                                 capture_output=True, text=True, check=True).stdout
        provided = {line.split(":")[0] for line in closure.splitlines() if line and not line.startswith(" ")}
        for binary in binaries:
            ldd = subprocess.run(["ldd", binary], capture_output=True, text=True, check=True).stdout
            for lib in re.findall(r"=> (/\S+)", ldd):
                owner = subprocess.run(["dpkg", "-S", os.path.realpath(lib)], capture_output=True, text=True)
                if owner.returncode:
                    owner = subprocess.run(["dpkg", "-S", lib], capture_output=True, text=True)
                package = owner.stdout.split(":")[0]
                self.assertIn(package, provided, f"{binary} loads {lib} from {package}, which the runtime set lacks")


if __name__ == "__main__":
    unittest.main(verbosity=2)
