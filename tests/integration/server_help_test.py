"""scenestreamer-server --help: exits 0 without starting, and lists exactly the flags server/main.cc defines, each with
the default Abseil holds for it (read back from --helpfull, Abseil's own listing), in the layout of the tools' --help
(common/command_line.h)."""
import os
import re
import subprocess
import unittest

SERVER = os.environ["SS_SERVER"]
MAIN = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "server", "main.cc")


class ServerHelpTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.help = subprocess.run([SERVER, "--help"], capture_output=True, text=True, timeout=60)
        cls.full = subprocess.run([SERVER, "--helpfull"], capture_output=True, text=True, timeout=60).stdout
        with open(MAIN) as f:
            cls.defined = set(re.findall(r"ABSL_FLAG\(\s*[\w:]+\s*,\s*(\w+)\s*,", f.read()))

    def test_exits_zero_with_the_usage(self):
        self.assertEqual(self.help.returncode, 0, self.help.stderr)
        self.assertTrue(self.help.stdout.startswith("usage: scenestreamer-server "), self.help.stdout[:200])
        self.assertNotIn("No flags matched", self.help.stdout + self.help.stderr)
        self.assertNotIn("serving", self.help.stdout + self.help.stderr)

    def test_lists_every_server_flag_with_its_default(self):
        listed = dict(re.findall(r"^  --(\w+) \(default: (.*)\)$", self.help.stdout, re.M))
        self.assertGreater(len(self.defined), 20)
        self.assertEqual(set(listed), self.defined)
        # Abseil's --helpfull: a block `    --name (help); default: VALUE;` per flag, wrapped, strings in quotes.
        abseil = {}
        for block in re.split(r"\n    --", self.full)[1:]:
            m = re.match(r"(\w+) \(.*\);\s+default: (.*?);\s*$", block.split("\n\n")[0], re.S)
            if m:
                abseil[m.group(1)] = m.group(2)
        for name, default in listed.items():
            self.assertIn(name, abseil)
            self.assertEqual(default, abseil[name], name)
        self.assertEqual(listed["port"], "50051")
        self.assertEqual(listed["host"], '"127.0.0.1"')
        self.assertEqual(listed["scenario_dir"], '""')

    def test_each_flag_has_its_help(self):
        blocks = re.split(r"^  --", self.help.stdout, flags=re.M)[1:]
        for block in blocks:
            name = block.split(" ", 1)[0]
            lines = block.splitlines()[1:]
            self.assertTrue(lines and all(l.startswith("      ") for l in lines), name)
        self.assertRegex(self.help.stdout, r"--scenario_dir \(default: \"\"\)\n(      .*\n)*.*bundled sample scenarios")

    def test_a_bad_flag_is_still_refused(self):
        r = subprocess.run([SERVER, "--no_such_flag=1"], capture_output=True, text=True, timeout=60)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("no_such_flag", r.stderr)


if __name__ == "__main__":
    unittest.main(verbosity=2)
