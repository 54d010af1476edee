// The wire messages (proto/voxel.proto, package vox.wire) through protobufjs. The schema
// is the JSON that tools/generate.js made from proto/voxel.proto at build time; field
// names are the .proto's (snake_case). uint64 fields decode as protobufjs Longs: use
// toBigInt() on them.
import protobuf from "protobufjs/light.js";
import schema from "./generated/voxel_proto.js";

export const root = protobuf.Root.fromJSON(schema);
export const Envelope = root.lookupType("vox.wire.Envelope");
const Long = protobuf.util.Long;

/** Names of the enums, for messages and errors. */
export const ErrorCode = root.lookupEnum("vox.wire.Error.Code").values;
export const EditStatus = root.lookupEnum("vox.wire.EditResult.Status").values;
export const RegionStatus = root.lookupEnum("vox.wire.RegionResult.Status").values;
export const StampShape = root.lookupEnum("vox.wire.Stamp.Shape").values;
export const QueryStatus = root.lookupEnum("vox.wire.QueryResult.Status").values;
const names = (values) => Object.fromEntries(Object.entries(values).map(([k, v]) => [v, k]));
export const errorCodeName = (code) => names(ErrorCode)[code] ?? `code ${code}`;
export const editStatusName = (status) => names(EditStatus)[status] ?? `status ${status}`;
export const queryStatusName = (status) => names(QueryStatus)[status] ?? `status ${status}`;

/**
 * A uint64 field as a BigInt (protobufjs gives a Long, a number, or a string).
 * @param {any} v
 * @returns {bigint}
 */
export function toBigInt(v) {
  if (v === undefined || v === null) return 0n;
  if (typeof v === "bigint") return v;
  if (typeof v === "number") return BigInt(v);
  return BigInt(v.toString());
}

/**
 * A value for a uint64 field from a number or BigInt.
 * @param {number|bigint} v
 */
export function toUint64(v) {
  if (typeof v === "bigint") return Long.fromString(v.toString(), true);
  return Long.fromNumber(v, true);
}

/**
 * Serializes an Envelope with exactly one body field, e.g. {hello: {...}}.
 * @param {object} body
 * @returns {Uint8Array}
 */
export function encodeEnvelope(body) {
  const keys = Object.keys(body);
  if (keys.length !== 1) throw new Error("an Envelope carries exactly one message");
  const err = Envelope.verify(body);
  if (err) throw new Error(`Envelope: ${err}`);
  return Envelope.encode(Envelope.create(body)).finish();
}

/**
 * Parses an Envelope. Returns {kind, message}: kind is the body's field name
 * ("welcome", "chunk_mesh", ...) or null for a body this schema does not know.
 * @param {Uint8Array} bytes
 * @returns {{kind: string|null, message: any}}
 */
export function decodeEnvelope(bytes) {
  const env = Envelope.decode(bytes);
  const kind = env.body ?? null;
  return { kind, message: kind ? env[kind] : null };
}
