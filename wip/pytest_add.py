

class PythonClientTest(unittest.TestCase):
    """The RL package's connect() and environments with a token and a TLS root certificate."""

    def test_the_package_connects_with_a_token_and_a_tls_root(self):
        import numpy as np

        from scenestreamer import SceneStreamerEnv
        from scenestreamer.client import connect
        pki = Pki()
        self.addCleanup(pki.close)
        tokens = pki.path("tokens.txt")
        with open(tokens, "w") as f:
            f.write(f"{ALICE} alice\n")
        with Server(f"--tls_cert={pki.path('server.pem')}", f"--tls_key={pki.path('server.key')}",
                    f"--tokens_file={tokens}", tls_root=pki.read("ca.pem"), token=ALICE) as srv:
            for root in (pki.path("ca.pem"), pki.read("ca.pem")):  # a path or the PEM bytes
                channel, stub = connect(srv.target, token=ALICE, tls_root=root, route=True)
                self.assertTrue(stub.ListScenarios(pb.ListScenariosRequest(), timeout=30).scenarios)
                channel.close()
            for token, root, code in ((None, pki.path("ca.pem"), C.UNAUTHENTICATED), (ALICE, None, C.UNAVAILABLE)):
                channel, stub = connect(srv.target, token=token, tls_root=root)
                self.assertEqual(error_of(stub.ListScenarios, pb.ListScenariosRequest(), timeout=10)[0], code)
                channel.close()
            env = SceneStreamerEnv(srv.target, max_steps=2, token=ALICE, tls_root=pki.path("ca.pem"))
            obs, info = env.reset(seed=1)
            _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
            self.assertEqual(info["tick"], 1)
            env.close()
        # Bad arguments are refused before any connection, naming what is wrong.
        with self.assertRaisesRegex(ValueError, "tls_root '/nonexistent/ca.pem': cannot read it"):
            connect("127.0.0.1:1", tls_root="/nonexistent/ca.pem")
        with self.assertRaisesRegex(ValueError, "hold no PEM certificate"):
            connect("127.0.0.1:1", tls_root=b"not a certificate")
        for token in ("", "two words", 42):
            with self.assertRaisesRegex(ValueError, "token: a non-empty string"):
                connect("127.0.0.1:1", token=token)
