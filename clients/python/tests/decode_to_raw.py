"""Decodes one mesh encoding file (format 1 or 2) with the reference client and writes its
positions (float32 xyz) and triangles (uint32) to a raw file, for a test in another
language to compare: decode_to_raw.py ENCODING OUT."""
import struct
import sys

import harness  # noqa: F401  (puts the package on sys.path)
from voxelclient import decode, load_table, proto


def main():
    with open(sys.argv[1], "rb") as f:
        mesh = decode(f.read(), load_table(proto.DEFAULT_TABLE))
    with open(sys.argv[2], "wb") as f:
        f.write(struct.pack("<II", mesh.vertex_count, mesh.triangle_count))
        f.write(mesh.positions.tobytes())
        f.write(mesh.triangles.tobytes())
        f.write(mesh.materials)


if __name__ == "__main__":
    main()
