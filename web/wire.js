// The browser viewer's frame message (docs/protocol.md, "Browser viewer"): one binary WebSocket
// message per frame, all little-endian.

/** Bytes before `d`. */
export const FRAME_FIXED_BYTES = 80;

/** Status byte names (as the TCP FRAME's). */
export const STATUS = ['calibrating', 'tracked', 'lost', 'rejected'];

/**
 * Decodes one frame message.
 * @param {ArrayBuffer} buf
 */
export function parseFrame(buf) {
  if (buf.byteLength < FRAME_FIXED_BYTES) {
    throw new Error(`frame message of ${buf.byteLength} bytes, at least ${FRAME_FIXED_BYTES} expected`);
  }
  const v = new DataView(buf);
  const m = v.getUint32(36, true);
  const k = v.getUint32(40, true);
  const want = FRAME_FIXED_BYTES + 12 * m + 4 * k;
  if (buf.byteLength !== want) {
    throw new Error(`frame message of ${buf.byteLength} bytes, ${want} expected for m=${m}, k=${k}`);
  }
  const f32 = (n, at) => {
    const out = new Float32Array(n);
    for (let i = 0; i < n; i++) out[i] = v.getFloat32(at + 4 * i, true);
    return out;
  };
  return {
    seq: Number(v.getBigUint64(0, true)),
    tUs: Number(v.getBigInt64(8, true)),
    arrivalUs: Number(v.getBigInt64(16, true)),
    sentUs: Number(v.getBigInt64(24, true)),
    status: v.getUint8(32),
    hasWeights: (v.getUint8(33) & 1) === 1,
    m,
    k,
    gated: v.getUint32(44, true),
    rotation: f32(4, 48),
    translation: f32(3, 64),
    scale: v.getFloat32(76, true),
    d: f32(3 * m, FRAME_FIXED_BYTES),
    weights: f32(k, FRAME_FIXED_BYTES + 12 * m),
  };
}
