#!/usr/bin/python3
"""Writes a NIfTI-1 volume (.nii or .nii.gz) as raw float32 little-endian, x fastest: the
input the VTK peer (../shared/peers) reads. Optionally upsampled K times per axis by
repeating samples (a label atlas resampled to a finer grid). Prints "OUT X Y Z".

    /usr/bin/python3 bench/scripts/nifti_to_raw.py IN.nii.gz OUT.raw [K]

Needs python3-numpy."""
import gzip
import struct
import sys

import numpy as np

TYPES = {2: "u1", 4: "i2", 8: "i4", 16: "f4", 64: "f8", 256: "i1", 512: "u2", 768: "u4"}

src, out = sys.argv[1], sys.argv[2]
k = int(sys.argv[3]) if len(sys.argv) > 3 else 1
data = (gzip.open if src.endswith(".gz") else open)(src, "rb").read()
order = "<" if struct.unpack("<i", data[:4])[0] == 348 else ">"
dim = struct.unpack(order + "8h", data[40:56])
datatype = struct.unpack(order + "h", data[70:72])[0]
offset = int(struct.unpack(order + "f", data[108:112])[0])
slope, inter = struct.unpack(order + "2f", data[112:120])
nx, ny, nz = dim[1:4]
v = np.frombuffer(data, order + TYPES[datatype], nx * ny * nz, offset).astype(np.float32)
if slope not in (0.0,) and np.isfinite(slope):
    v = v * np.float32(slope) + np.float32(inter)
v = v.reshape(nz, ny, nx)
if k > 1:
    v = v.repeat(k, 0).repeat(k, 1).repeat(k, 2)
np.ascontiguousarray(v, "<f4").tofile(out)
print(out, v.shape[2], v.shape[1], v.shape[0])
