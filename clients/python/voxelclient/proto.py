"""Generates the protobuf bindings of proto/voxel.proto with protoc and imports them.

Nothing generated is kept in the source tree: the module is written to a directory of
the caller's choosing (a temporary one by default) and imported from there.
"""
import atexit
import importlib.util
import os
import shutil
import subprocess
import tempfile

_HERE = os.path.dirname(os.path.abspath(__file__))
REPO_ROOT = os.path.normpath(os.path.join(_HERE, "..", "..", ".."))
DEFAULT_PROTO = os.path.join(REPO_ROOT, "proto", "voxel.proto")
DEFAULT_TABLE = os.path.join(REPO_ROOT, "docs", "marching_cubes_tables.txt")

_cache = {}


def load(proto_path=None, out_dir=None, protoc=None):
    """Returns the generated `voxel_pb2` module (cached per proto path)."""
    proto_path = os.path.abspath(proto_path or os.environ.get("VOXEL_PROTO", DEFAULT_PROTO))
    if proto_path in _cache:
        return _cache[proto_path]
    protoc = protoc or os.environ.get("PROTOC", "protoc")
    if out_dir is None:
        out_dir = tempfile.mkdtemp(prefix="voxel_pb2_")
        atexit.register(shutil.rmtree, out_dir, True)
    proto_dir, name = os.path.split(proto_path)
    subprocess.run([protoc, "-I", proto_dir, "--python_out", out_dir, name],
                   check=True, capture_output=True, timeout=60)
    module_name = os.path.splitext(name)[0] + "_pb2"
    path = os.path.join(out_dir, module_name + ".py")
    spec = importlib.util.spec_from_file_location(module_name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    _cache[proto_path] = module
    return module
