// The binary tool-path preview (`GET /api/programs/{name}/preview?format=binary`; its layout
// is crates/api/src/preview.rs `encode_binary`): one chain of points, read without parsing.
import type { ProgramError } from './types';

export const KIND_START = 0;
export const KIND_RAPID = 1;
export const KIND_FEED = 2;

export interface PathChain {
  /** Points: X Y Z (mm, the canonical frame: work offsets applied, no tool length). */
  positions: Float32Array;
  /** Program line of the move ending at each point (0 for the first). */
  lines: Uint32Array;
  /** KIND_START, KIND_RAPID or KIND_FEED: how each point is reached. */
  kinds: Uint8Array;
  /** Path length from the first point to each point, mm. */
  distance: Float64Array;
  min: [number, number, number];
  max: [number, number, number];
  errors: ProgramError[];
  count: number;
}

const MAGIC = 'RTCNCPV1';

export function decodePreview(buffer: ArrayBuffer): PathChain {
  const bytes = new Uint8Array(buffer);
  if (bytes.length < 40 || String.fromCharCode(...bytes.subarray(0, 8)) !== MAGIC) {
    throw new Error('not a binary preview');
  }
  const view = new DataView(buffer);
  const n = view.getUint32(8, true);
  const m = view.getUint32(12, true);
  if (bytes.length !== 40 + 17 * n + m) throw new Error('binary preview of the wrong length');
  const f = (i: number) => view.getFloat32(16 + 4 * i, true);
  // Little-endian typed views: every browser this runs on is little-endian.
  const positions = new Float32Array(buffer, 40, 3 * n);
  const lines = new Uint32Array(buffer, 40 + 12 * n, n);
  const kinds = new Uint8Array(buffer, 40 + 16 * n, n);
  const errors = JSON.parse(new TextDecoder().decode(bytes.subarray(40 + 17 * n))) as ProgramError[];
  const distance = new Float64Array(n);
  for (let i = 1; i < n; i++) {
    const dx = positions[3 * i] - positions[3 * i - 3];
    const dy = positions[3 * i + 1] - positions[3 * i - 2];
    const dz = positions[3 * i + 2] - positions[3 * i - 1];
    distance[i] = distance[i - 1] + Math.sqrt(dx * dx + dy * dy + dz * dz);
  }
  return { positions, lines, kinds, distance, min: [f(0), f(1), f(2)], max: [f(3), f(4), f(5)], errors, count: n };
}

/** How far a run has gone along the chain: the index of the last point reached. */
export interface Cursor {
  index: number;
}

/** Points searched past the cursor for the executing line (a loop's body comes again). */
const SEARCH = 200_000;

/**
 * Moves the cursor to where the tool is: along the chain from where it is to the run of
 * points of the executing `line`, then to the segment of that run nearest the tool (`tool`,
 * in the chain's frame): the cursor is the segment's first point, or its last once the tool
 * is there. It never goes back: lines come again in loops and subroutines, and the chain
 * has them in the order they run.
 */
export function advance(chain: PathChain, cursor: Cursor, line: number, tool: [number, number, number]): Cursor {
  const { lines, positions, count } = chain;
  if (count === 0 || line <= 0) return cursor;
  const from = Math.max(cursor.index, 0);
  const end = Math.min(count, from + SEARCH);
  let start = -1;
  for (let k = Math.max(from, 1); k < end; k++) {
    if (lines[k] === line) {
      start = k;
      break;
    }
  }
  if (start < 0) return cursor;
  let best = start - 1;
  let bestD = Infinity;
  for (let k = start; k < count && lines[k] === line && k < start + SEARCH; k++) {
    const ax = positions[3 * k - 3], ay = positions[3 * k - 2], az = positions[3 * k - 1];
    const sx = positions[3 * k] - ax, sy = positions[3 * k + 1] - ay, sz = positions[3 * k + 2] - az;
    const len2 = sx * sx + sy * sy + sz * sz;
    let t = len2 > 0 ? ((tool[0] - ax) * sx + (tool[1] - ay) * sy + (tool[2] - az) * sz) / len2 : 1;
    t = Math.min(1, Math.max(0, t));
    const dx = ax + t * sx - tool[0], dy = ay + t * sy - tool[1], dz = az + t * sz - tool[2];
    const d = dx * dx + dy * dy + dz * dz;
    // Ties go to the earlier segment: a canned cycle runs back over its own path.
    if (d < bestD) {
      bestD = d;
      best = t >= 0.999 ? k : k - 1;
    }
  }
  return { index: Math.max(best, from) };
}

/** The first point of a run from `line` on (run from line). */
export function indexOfLine(chain: PathChain, line: number): number {
  for (let k = 0; k < chain.count; k++) if (chain.lines[k] >= line) return Math.max(k - 1, 0);
  return Math.max(chain.count - 1, 0);
}
