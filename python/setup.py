"""Builds the package with its gRPC stubs generated from the repository's proto/ (never committed): the stubs are
written into the build tree as the subpackage scenestreamer.v1, so the installed package imports without the
repository or the C++ build on the path."""
import os
import shutil
import subprocess

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = os.path.dirname(os.path.abspath(__file__))


def generate_stubs(out_dir, proto_dir=os.path.join(HERE, "..", "proto")):
    """Writes scenestreamer/v1/simulator_pb2{,_grpc}.py under out_dir with Debian's protoc (protobuf-compiler) and
    gRPC Python plugin (protobuf-compiler-grpc). Not python3-grpc-tools: its bundled protoc (3.6) predates proto3
    `optional`, which the API uses."""
    proto = os.path.join(proto_dir, "scenestreamer", "v1", "simulator.proto")
    if not os.path.exists(proto):
        raise RuntimeError(f"{proto} not found: build the package from the SceneStreamer repository (python/)")
    protoc = shutil.which("protoc")
    plugin = shutil.which("grpc_python_plugin")
    if not protoc or not plugin:
        raise RuntimeError("protoc and grpc_python_plugin are needed to build the stubs (Debian: protobuf-compiler, "
                           "protobuf-compiler-grpc; deploy/install-deps.sh installs them)")
    os.makedirs(os.path.join(out_dir, "scenestreamer", "v1"), exist_ok=True)
    subprocess.run([protoc, f"-I{proto_dir}", f"--python_out={out_dir}", f"--grpc_out={out_dir}",
                    f"--plugin=protoc-gen-grpc={plugin}", proto], check=True)
    # protoc writes no __init__.py for the package it generates into.
    open(os.path.join(out_dir, "scenestreamer", "v1", "__init__.py"), "w").close()


class BuildWithStubs(build_py):
    def run(self):
        super().run()
        if not self.dry_run:
            generate_stubs(self.build_lib)


if __name__ == "__main__":
    setup(cmdclass={"build_py": BuildWithStubs})
