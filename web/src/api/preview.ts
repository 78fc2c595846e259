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

/** The points of a chain that are drawn, with the chain index of each (for what has run). */
export interface DrawnPath {
  positions: Float32Array;
  kinds: Uint8Array;
  /** Chain index of each drawn point, as a float (exact below 2^24). */
  index: Float32Array;
  count: number;
}

/**
 * The chain with the points dropped that lie within `tolerance` (mm) of the straight line
 * the path follows (Reumann-Witkam: one pass, no allocation per point): a CAM program's
 * million short segments on lines and gentle curves become the few thousand a panel can
 * show apart, every dropped point within `tolerance` of the line drawn through it. The
 * first and last points, the ends of every rapid and feed run and every turn back along
 * the line are kept; a drawn segment ending at chain point j stands for the chain's
 * segments up to j, all of one kind.
 */
export function simplifyForDrawing(chain: PathChain, tolerance: number): DrawnPath {
  const { positions: p, kinds: k, count: n } = chain;
  const keep = new Uint32Array(Math.max(n, 1));
  let m = 0;
  const tol2 = tolerance * tolerance;
  let a = 0;
  let dx = 0;
  let dy = 0;
  let dz = 0;
  let hasDir = false;
  let tMax = 0;
  /** Starts a new line at kept point `i`, aimed at point `j` if it is far enough. */
  const restart = (i: number, j: number) => {
    a = i;
    keep[m++] = i;
    aim(j);
  };
  const aim = (j: number) => {
    const vx = p[3 * j] - p[3 * a];
    const vy = p[3 * j + 1] - p[3 * a + 1];
    const vz = p[3 * j + 2] - p[3 * a + 2];
    const len = Math.sqrt(vx * vx + vy * vy + vz * vz);
    hasDir = len > tolerance;
    if (hasDir) {
      dx = vx / len;
      dy = vy / len;
      dz = vz / len;
      tMax = len;
    }
  };
  if (n > 0) keep[m++] = 0;
  for (let i = 1; i < n; i++) {
    if (i > 1 && k[i] !== k[i - 1] && a !== i - 1) {
      restart(i - 1, i);
      continue;
    }
    if (!hasDir) {
      aim(i);
      continue;
    }
    const vx = p[3 * i] - p[3 * a];
    const vy = p[3 * i + 1] - p[3 * a + 1];
    const vz = p[3 * i + 2] - p[3 * a + 2];
    const t = vx * dx + vy * dy + vz * dz;
    const perp2 = vx * vx + vy * vy + vz * vz - t * t;
    if (perp2 > tol2 || t < tMax - tolerance) {
      restart(i - 1, i);
    } else if (t > tMax) {
      tMax = t;
    }
  }
  if (n > 1 && keep[m - 1] !== n - 1) keep[m++] = n - 1;
  const positions = new Float32Array(3 * m);
  const kinds = new Uint8Array(m);
  const index = new Float32Array(m);
  for (let q = 0; q < m; q++) {
    const i = keep[q];
    positions[3 * q] = p[3 * i];
    positions[3 * q + 1] = p[3 * i + 1];
    positions[3 * q + 2] = p[3 * i + 2];
    kinds[q] = k[i];
    index[q] = i;
  }
  return { positions, kinds, index, count: m };
}
