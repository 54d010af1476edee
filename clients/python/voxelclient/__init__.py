"""voxelclient: the reference Python client of voxeld, written from docs/PROTOCOL.md."""
from .client import Chunk, Client, QueryAnswer, ServerError, coord_of, volumes
from .compression import CompressionError, decompress_delta, decompress_full
from .framing import FrameError, FrameReader, encode_frame
from .mesh import Mesh, MeshError, check_crc, crc32c, decode, load_table, octahedral
from . import proto

__all__ = ["Chunk", "Client", "QueryAnswer", "ServerError", "coord_of", "volumes",
           "CompressionError", "decompress_delta", "decompress_full", "FrameError", "FrameReader",
           "encode_frame", "Mesh", "MeshError", "check_crc", "crc32c", "decode",
           "load_table", "octahedral", "proto"]
