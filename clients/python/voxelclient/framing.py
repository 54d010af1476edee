"""Length-prefixed frames on a TCP stream (PROTOCOL.md section 4.1)."""
import socket
import struct
import time

MAX_SERVER_FRAME = 16 << 20  # "Accept at least 16 MiB"


class FrameError(Exception):
    """The stream broke inside a frame, or a frame was over the limit."""


def encode_frame(payload):
    return struct.pack("<I", len(payload)) + payload


class FrameReader:
    """Reads whole frames from a socket, each read bounded by a deadline."""

    def __init__(self, sock, max_frame=MAX_SERVER_FRAME):
        self.sock = sock
        self.max_frame = max_frame
        self.buf = bytearray()
        self.closed = False

    def _take(self):
        if len(self.buf) < 4:
            return None
        (size,) = struct.unpack_from("<I", self.buf, 0)
        if size > self.max_frame:
            raise FrameError("server frame of %d bytes is over the limit" % size)
        if len(self.buf) < 4 + size:
            return None
        frame = bytes(self.buf[4:4 + size])
        del self.buf[:4 + size]
        return frame

    def read(self, deadline):
        """Next frame; None when the peer closed between frames.

        Raises socket.timeout when the deadline (time.monotonic()) passes first.
        """
        while True:
            frame = self._take()
            if frame is not None:
                return frame
            if self.closed:
                if self.buf:
                    raise FrameError("connection closed inside a frame")
                return None
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise socket.timeout("no frame before the deadline")
            self.sock.settimeout(remaining)
            try:
                data = self.sock.recv(1 << 16)
            except ConnectionResetError:
                data = b""
            if not data:
                self.closed = True
            self.buf += data
