"""The server binary holds the runtime library only (engine/CMakeLists.txt): none of the offline tools library's code
(offline/dataset: the SUMO converters, offline/eval: the metrics, offline/render: SVG) is linked into it.

Every strong global symbol a tools object file defines (nm types T, D, B, R) must be absent from the server's defined
symbols: a static archive member is linked whole, so one such symbol present means a tools object came in. Weak
symbols (inline functions, template instances such as std::vector<double>) are shared by both sides and not counted.
Run with SS_SERVER and SS_OFFLINE_LIB set (tests/CMakeLists.txt)."""
import os
import subprocess
import unittest

STRONG = set("TDBR")


def defined(path, types):
    out = subprocess.run(["nm", "--defined-only", path], check=True, capture_output=True, text=True).stdout
    symbols = set()
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[1] in types:
            symbols.add(parts[2])
    return symbols


class ServerSymbolsTest(unittest.TestCase):
    def test_no_tools_code_in_the_server(self):
        tools = defined(os.environ["SS_OFFLINE_LIB"], STRONG)
        server = defined(os.environ["SS_SERVER"], STRONG | set("tdbrWwVv"))
        # Not vacuous: the tools library defines the metrics and converters, the server the runtime's door.
        demangled = subprocess.run(["c++filt"], input="\n".join(sorted(tools)), capture_output=True, text=True,
                                   check=True).stdout
        self.assertIn("ss::wosac_2025_config()", demangled)
        self.assertIn("ss::parse_sumo_net(", demangled)
        self.assertTrue(any(s.startswith("_ZN2ss13engine_create") for s in server),
                        "the server defines none of the runtime's door (engine/scenestreamer.h)")
        both = sorted(tools & server)
        self.assertEqual(both, [], "tools-library symbols in the server:\n" + subprocess.run(
            ["c++filt"], input="\n".join(both[:20]), capture_output=True, text=True).stdout)


if __name__ == "__main__":
    unittest.main()
