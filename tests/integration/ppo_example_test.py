"""The PPO example (client_examples/python/ppo.py --quick) end to end against two real servers on loopback, one
serving a training scenario and one a held-out one: one real PPO iteration (2 environments x 8 steps, the update),
then the held-out evaluation of the trained, cruise and random policies. Fails if any part of the loop breaks: the
script's exit code, the iteration's log row (steps, episodes, finite losses), the weights it saved (moved by the
update), the evaluation's episodes and the plot."""
import json
import math
import os
import subprocess
import sys
import shutil
import tempfile
import unittest

import torch

from server_process import DATA, Server

EXAMPLES = os.environ["SS_PY_CLIENT_DIR"]
sys.path.insert(0, EXAMPLES)
import ppo  # noqa: E402


class PpoExampleTest(unittest.TestCase):
    def test_quick_run(self):
        out = tempfile.mkdtemp(prefix="ss-ppo-")
        self.addCleanup(shutil.rmtree, out, True)
        # Two servers on disjoint scenarios (a later --scenario_dir overrides the Server's default).
        with Server(f"--scenario_dir={os.path.join(DATA, 'motion_data_one_scenario.tfrecord')}") as train, \
                Server(f"--scenario_dir={os.path.join(DATA, 'womd_scenario_input.tfrecord')}") as held_out:
            r = subprocess.run([sys.executable, os.path.join(EXAMPLES, "ppo.py"), "--quick", "--out", out,
                                "--train-target", train.target, "--eval-target", held_out.target],
                               capture_output=True, text=True, timeout=300)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            # The same server for both is refused: the evaluation must be on held-out scenarios.
            same = subprocess.run([sys.executable, os.path.join(EXAMPLES, "ppo.py"), "--quick", "--out", out,
                                   "--train-target", train.target, "--eval-target", train.target],
                                  capture_output=True, text=True, timeout=120)
            self.assertNotEqual(same.returncode, 0)
            self.assertIn("training scenarios", same.stderr)

        with open(os.path.join(out, "log.jsonl")) as f:
            rows = [json.loads(line) for line in f]
        self.assertEqual(len(rows), 1, rows)
        row = rows[0]
        self.assertEqual(row["env_steps"], 16)  # 2 envs x 8 steps
        self.assertGreaterEqual(row["episodes"], 2)  # episodes of at most 6 steps: each env ends one at least
        for key in ("mean_return", "policy_loss", "value_loss", "entropy"):
            self.assertTrue(math.isfinite(row[key]), (key, row))
        for key in ("collision_rate", "offroad_rate", "red_light_rate"):
            self.assertTrue(0.0 <= row[key] <= 1.0, (key, row))

        # The update moved the weights away from their initialisation (the script seeds torch with --seed 0).
        torch.manual_seed(0)
        initial = ppo.ActorCritic(24, 64).state_dict()  # 24 features, --hidden 64
        trained = torch.load(os.path.join(out, "policy.pt"))
        self.assertEqual({k: v.shape for k, v in initial.items()}, {k: v.shape for k, v in trained.items()})
        self.assertTrue(any(not torch.equal(initial[k], trained[k]) for k in initial))

        with open(os.path.join(out, "eval.json")) as f:
            ev = json.load(f)
        self.assertEqual(ev["iterations"], 1)
        for label in ("ppo", "cruise", "random"):
            self.assertEqual(ev[label]["summary"]["episodes"], 2, label)
            self.assertEqual([e["seed"] for e in ev[label]["episodes"]], [10_000, 10_001])
            for e in ev[label]["episodes"]:
                self.assertTrue(1 <= e["length"] <= 6, e)
                self.assertTrue(math.isfinite(e["return"]))
        with open(os.path.join(out, "curves.svg")) as f:
            svg = f.read()
        self.assertTrue(svg.startswith("<svg") and svg.rstrip().endswith("</svg>"))
        self.assertIn("collision rate", svg)


if __name__ == "__main__":
    unittest.main(verbosity=2)
