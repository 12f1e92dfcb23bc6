// The page's reader and writer of the study server's messages: a mirror of
// study/web/messages.py, which is the specification (keep the two in step).
export const STATE = 1, CAMERA = 2, MAP = 3, INPUT = 1;
export const KEYS = ["forward", "back", "left", "right", "turn_left", "turn_right", "yes",
  "no", "pause", "arrow_up", "arrow_down", "arrow_left", "arrow_right", "enter"];
const STATE_HEAD = 36, CAMERA_HEAD = 8, MAP_HEAD = 24;

export function kindOf(buffer) {
  return new DataView(buffer).getUint8(0);
}

export function unpackState(buffer) {
  const v = new DataView(buffer);
  const n = v.getUint16(2, true);
  const f = (o) => v.getFloat32(o, true);
  const points = new Int16Array(buffer, STATE_HEAD, 2 * n);
  return {
    paused: (v.getUint8(1) & 1) === 1, tick: v.getUint32(4, true), t: f(8),
    pose: [f(12), f(16), f(20)], stick: [f(24), f(28), f(32)], points,
  };
}

export function unpackCamera(buffer) {
  const v = new DataView(buffer);
  return {
    which: v.getUint8(1) === 1 ? "tail" : "front", tick: v.getUint32(4, true),
    jpeg: new Uint8Array(buffer, CAMERA_HEAD),
  };
}

export function unpackMap(buffer) {
  const v = new DataView(buffer);
  const cols = v.getUint16(8, true), rows = v.getUint16(10, true);
  return {
    id: v.getUint32(4, true), cols, rows, resolution: v.getFloat32(12, true),
    origin: [v.getFloat32(16, true), v.getFloat32(20, true)],
    cells: new Uint8Array(buffer, MAP_HEAD, rows * cols),
  };
}

export function packInput(seq, lastTick, axes, buttons, keys, gamepad) {
  const b = new ArrayBuffer(32), v = new DataView(b);
  v.setUint8(0, INPUT); v.setUint8(1, gamepad ? 1 : 0); v.setUint16(2, buttons, true);
  v.setUint32(4, seq, true); v.setUint32(8, lastTick >>> 0, true);
  for (let i = 0; i < 4; i++) v.setFloat32(12 + 4 * i, axes[i] || 0, true);
  v.setUint32(28, keys, true);
  return b;
}
