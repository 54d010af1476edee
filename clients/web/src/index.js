// voxeld's JavaScript client: the browser-safe entry point (no Node-only import). The
// Node TCP transport is "voxeld-client/tcp" (src/transport_tcp.js).
export { Client, ServerError, decodeSamples, editBody, plain, queryBody } from "./client.js";
export { ChunkCache, chunkKey } from "./chunks.js";
export { CompressionError, decompressDelta, decompressFull, inspectFrame, MAX_CONTENT_BYTES, MAX_WINDOW_LOG } from "./compression.js";
export { crc32c } from "./crc32c.js";
export { encodeFrame, FrameDecoder, FrameError, MAX_SERVER_FRAME_BYTES } from "./framing.js";
export { decodeMesh, MAX_ENCODING_BYTES, MeshDecodeError, seamCells } from "./mesh.js";
export { decodeEnvelope, EditStatus, encodeEnvelope, ErrorCode, QueryStatus, StampShape, toBigInt } from "./messages.js";
export { DEFAULT_TABLE, parseTable } from "./table.js";
export { connectWebSocket, WebSocketTransport } from "./transport_ws.js";
