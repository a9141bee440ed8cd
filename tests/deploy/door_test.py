"""Hosts reach the engine through its door (docs/design.md section 3).

A host is a program built on the engine: server/, client_examples/, tools/, bench/, viewer/, and common/ (what the
programs share: the command line, the allocator's settings, the bench world). Each #include of an engine header in a
host's source is checked:
- server/ and client_examples/ include engine/scenestreamer.h and nothing else of engine/, except the headers of
  SHARED: helpers that sit in engine/ but link no engine code (own CMake targets); and nothing of offline/;
- tools/, bench/, viewer/ and common/ are offline hosts (inspection, conversion, evaluation, micro-benchmarks of the
  kernels, the bench world, the viewer's gateway, which reads scenario files for their maps): they may
  include engine/scenestreamer.h, the offline door engine/offline.h (the model as the door loads it, and the
  headers a host needs to roll sessions out), and the engine headers listed in door_exceptions.txt beside this file, one
  "host-file engine-header" pair a line. The offline library's headers (offline/) are theirs to include. The list is exactly what they include past the door: an include that is not
  listed fails, and so does a listed pair that no longer exists, so a new line is a visible decision.
Run from anywhere: the repository is found from this file's place."""
import os
import re
import tempfile
import unittest

DOOR = "engine/scenestreamer.h"
OFFLINE_DOOR = "engine/offline.h"  # the model as the door loads it, and the headers a host needs to roll sessions out
SHARED = {
    "engine/io/json_text.h",  # target scenestreamer_json: the one JSON writer policy, header only
    "engine/io/file_io.h",  # target scenestreamer_file_io: whole-file reads, atomic writes
}
STRICT = ("server", "client_examples")
OFFLINE = ("tools", "bench", "viewer", "common")
INCLUDE = re.compile(r'^\s*#\s*include\s*[<"](engine/[^>"]+)[>"]', re.M)
OFFLINE_INCLUDE = re.compile(r'^\s*#\s*include\s*[<"](offline/[^>"]+)[>"]', re.M)
SOURCES = (".h", ".hpp", ".cc", ".cpp")
HERE = os.path.dirname(os.path.abspath(__file__))


def includes(root, folders, pattern):
    """(host file, header) for every include matching `pattern` in `folders` of `root`."""
    found = set()
    for folder in folders:
        for dirpath, dirs, files in os.walk(os.path.join(root, folder)):
            dirs[:] = [d for d in dirs if d not in ("node_modules", "dist")]  # the viewer page's packages and build
            for f in files:
                if not f.endswith(SOURCES):
                    continue
                path = os.path.join(dirpath, f)
                with open(path, encoding="utf-8", errors="replace") as src:
                    for header in pattern.findall(src.read()):
                        found.add((os.path.relpath(path, root), header))
    return found


def engine_includes(root, folders):
    """(host file, engine header) for every engine include in `folders` of `root`."""
    return includes(root, folders, INCLUDE)


def offline_includes(root, folders):
    """(host file, header) for every include of the offline library (offline/) in `folders` of `root`."""
    return includes(root, folders, OFFLINE_INCLUDE)


def read_exceptions(path):
    pairs = set()
    with open(path) as f:
        for n, line in enumerate(f, 1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            parts = line.split()
            if len(parts) != 2:
                raise ValueError(f"{path}:{n}: want 'host-file engine-header', got {line!r}")
            pairs.add(tuple(parts))
    return pairs


def violations(root, exceptions):
    """What breaks the rule in `root`: includes past the door, and listed exceptions that are gone."""
    problems = []
    for host, header in sorted(engine_includes(root, STRICT)):
        if header != DOOR and header not in SHARED:
            problems.append(f"{host} includes {header}: this host reaches the engine through {DOOR} only")
    for host, header in sorted(offline_includes(root, STRICT)):
        problems.append(f"{host} includes {header}: the offline library is never part of this host")
    offline = {p for p in engine_includes(root, OFFLINE) if p[1] not in (DOOR, OFFLINE_DOOR) and p[1] not in SHARED}
    for host, header in sorted(offline - exceptions):
        problems.append(f"{host} includes {header}, past the door and not in door_exceptions.txt: include {DOOR} "
                        f"or {OFFLINE_DOOR} (or list it if the host truly needs the internal header)")
    for host, header in sorted(exceptions - offline):
        problems.append(f"door_exceptions.txt lists '{host} {header}', which is no longer included: remove the line")
    return problems


class DoorTest(unittest.TestCase):
    def test_hosts_include_only_the_door(self):
        root = os.path.dirname(os.path.dirname(HERE))
        exceptions = read_exceptions(os.path.join(HERE, "door_exceptions.txt"))
        self.assertTrue(engine_includes(root, STRICT), "no host includes the door: the scan is looking elsewhere")
        self.assertEqual(violations(root, exceptions), [])
        self.assertFalse({h for h, _ in exceptions if h.split(os.sep)[0] in STRICT},
                         "door_exceptions.txt is for the offline hosts only")

    def test_the_check_sees_a_host_past_the_door(self):
        with tempfile.TemporaryDirectory() as root:
            for host, text in [("server/a.cc", '#include "engine/scenestreamer.h"\n#include "engine/model/model.h"\n'),
                               ("server/d.cc", '#include "offline/eval/evaluate.h"\n'),
                               ("tools/b.cc", '#include "engine/sim/session.h"\n#include "offline/eval/evaluate.h"\n'
                                '#include "engine/offline.h"\n'),
                               ("bench/c.cc", '#include "engine/scenestreamer.h"\n')]:
                os.makedirs(os.path.join(root, os.path.dirname(host)), exist_ok=True)
                with open(os.path.join(root, host), "w") as f:
                    f.write(text)
            got = violations(root, {("bench/c.cc", "engine/map/focus.h")})
            self.assertEqual(len(got), 4, got)
            self.assertIn("server/a.cc includes engine/model/model.h", got[0])
            self.assertIn("server/d.cc includes offline/eval/evaluate.h: the offline library is never", got[1])
            self.assertIn("tools/b.cc includes engine/sim/session.h, past the door", got[2])
            self.assertIn("lists 'bench/c.cc engine/map/focus.h', which is no longer included", got[3])
            self.assertEqual(violations(root, {("tools/b.cc", "engine/sim/session.h")})[2:], [])


if __name__ == "__main__":
    unittest.main()
