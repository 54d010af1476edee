"""zstd full frames and prefix deltas (PROTOCOL.md section 3)."""
import zstandard

MAX_CONTENT = 4 << 20  # voxeld's own decoder refuses over 4 MiB
WINDOW_LOG_MAX = 23
_UNKNOWN = (1 << 64) - 1  # ZSTD_CONTENTSIZE_UNKNOWN


class CompressionError(ValueError):
    pass


def _decompress(payload, dict_data):
    try:
        params = zstandard.get_frame_parameters(payload)
    except zstandard.ZstdError as e:
        raise CompressionError("not a zstd frame: %s" % e) from None
    size = params.content_size
    if size == _UNKNOWN:
        raise CompressionError("frame does not declare its content size")
    if size > MAX_CONTENT:
        raise CompressionError("frame declares %d bytes, over the limit" % size)
    dctx = zstandard.ZstdDecompressor(dict_data=dict_data,
                                      max_window_size=1 << WINDOW_LOG_MAX)
    dobj = dctx.decompressobj()
    try:
        out = dobj.decompress(payload)
    except zstandard.ZstdError as e:
        raise CompressionError("zstd: %s" % e) from None
    if not dobj.eof or dobj.unused_data:
        raise CompressionError("payload is not exactly one complete zstd frame")
    if len(out) != size:
        raise CompressionError("content is %d bytes, frame declared %d" % (len(out), size))
    return out


def decompress_full(payload):
    return _decompress(payload, None)


def decompress_delta(payload, base):
    """Decompresses a delta with `base` (the previous encoding) as raw-content prefix."""
    prefix = zstandard.ZstdCompressionDict(bytes(base), dict_type=zstandard.DICT_TYPE_RAWCONTENT)
    return _decompress(payload, prefix)
