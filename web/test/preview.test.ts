import { describe, expect, it } from 'vitest';
import { KIND_FEED, KIND_RAPID, KIND_START, advance, decodePreview, indexOfLine, simplifyForDrawing } from '../src/api/preview';

/** The binary layout of crates/api/src/preview.rs, written here by hand. */
function encode(points: [number, number, number][], lines: number[], kinds: number[], errors = '[]') {
  const n = points.length;
  const err = new TextEncoder().encode(errors);
  const buf = new ArrayBuffer(40 + 17 * n + err.length);
  const v = new DataView(buf);
  new Uint8Array(buf).set(new TextEncoder().encode('RTCNCPV1'), 0);
  v.setUint32(8, n, true);
  v.setUint32(12, err.length, true);
  const min = [0, 1, 2].map((i) => Math.min(...points.map((p) => p[i])));
  const max = [0, 1, 2].map((i) => Math.max(...points.map((p) => p[i])));
  [...min, ...max].forEach((x, i) => v.setFloat32(16 + 4 * i, x, true));
  points.forEach((p, i) => p.forEach((x, k) => v.setFloat32(40 + 12 * i + 4 * k, x, true)));
  lines.forEach((l, i) => v.setUint32(40 + 12 * n + 4 * i, l, true));
  kinds.forEach((k, i) => v.setUint8(40 + 16 * n + i, k));
  new Uint8Array(buf).set(err, 40 + 17 * n);
  return buf;
}

// A square by hand: a rapid to (0, 0, 5) (line 2), down at feed (line 3), then X to 10 in
// two chords of line 4 and Y to 10 (line 5).
const square = encode(
  [
    [0, 0, 10],
    [0, 0, 5],
    [0, 0, 0],
    [5, 0, 0],
    [10, 0, 0],
    [10, 10, 0],
  ],
  [0, 2, 3, 4, 4, 5],
  [KIND_START, KIND_RAPID, KIND_FEED, KIND_FEED, KIND_FEED, KIND_FEED],
);

describe('the binary preview', () => {
  it('is read without parsing: points, lines, kinds, bounds and path length', () => {
    const c = decodePreview(square);
    expect(c.count).toBe(6);
    expect([...c.positions.subarray(9, 12)]).toEqual([5, 0, 0]);
    expect([...c.lines]).toEqual([0, 2, 3, 4, 4, 5]);
    expect(c.kinds[1]).toBe(KIND_RAPID);
    expect(c.min).toEqual([0, 0, 0]);
    expect(c.max).toEqual([10, 10, 10]);
    // 5 + 5 + 10 + 10 mm.
    expect(c.distance[5]).toBeCloseTo(30, 6);
    expect(c.errors).toEqual([]);
  });

  it('carries the interpreter errors, and refuses what is not a preview', () => {
    const e = '[{"line":7,"column":3,"code":"G-SYNTAX","message":"number expected"}]';
    const c = decodePreview(encode([[0, 0, 0]], [0], [KIND_START], e));
    expect(c.errors[0].line).toBe(7);
    expect(() => decodePreview(new ArrayBuffer(40))).toThrow();
    expect(() => decodePreview(square.slice(0, 100))).toThrow();
  });
});

describe('the run along the path', () => {
  const c = decodePreview(square);

  it('follows the executing line and the tool within it', () => {
    let cur = { index: 0 };
    cur = advance(c, cur, 2, [0, 0, 7]);
    expect(cur.index).toBe(0);
    cur = advance(c, cur, 4, [2.5, 0, 0]);
    // On the first chord of line 4: from point 2 on.
    expect(cur.index).toBe(2);
    cur = advance(c, cur, 4, [7, 0, 0]);
    expect(cur.index).toBe(3);
    cur = advance(c, cur, 5, [10, 10, 0]);
    expect(cur.index).toBe(5);
  });

  it('never goes back, and ignores a line it does not find ahead', () => {
    const at = advance(c, { index: 4 }, 3, [0, 0, 0]);
    expect(at.index).toBe(4);
    expect(advance(c, { index: 2 }, 99, [0, 0, 0]).index).toBe(2);
  });

  it('gives where a line starts (run from line)', () => {
    expect(indexOfLine(c, 4)).toBe(2);
    expect(indexOfLine(c, 1)).toBe(0);
  });
});

describe('the drawn path', () => {
  /** Distance from point q to the segment a-b. */
  function toSegment(q: number[], a: number[], b: number[]): number {
    const ab = [0, 1, 2].map((i) => b[i] - a[i]);
    const aq = [0, 1, 2].map((i) => q[i] - a[i]);
    const l2 = ab.reduce((s, x) => s + x * x, 0);
    const t = l2 === 0 ? 0 : Math.max(0, Math.min(1, aq.reduce((s, x, i) => s + x * ab[i], 0) / l2));
    return Math.hypot(...[0, 1, 2].map((i) => aq[i] - t * ab[i]));
  }

  it('keeps the corners of a raster of short collinear segments, and the run kinds', () => {
    // Rapid down to (0,0,0), then three rows of ten 1 mm feeds, back and forth, 1 mm apart.
    const pts: [number, number, number][] = [[0, 0, 5], [0, 0, 0]];
    for (let r = 0; r < 3; r++) {
      if (r > 0) pts.push([r % 2 ? 10 : 0, r, 0]);
      for (let k = 1; k <= 10; k++) pts.push([r % 2 ? 10 - k : k, r, 0]);
    }
    const kinds = pts.map((_, i) => (i === 0 ? KIND_START : i === 1 ? KIND_RAPID : KIND_FEED));
    const c = decodePreview(encode(pts, pts.map((_, i) => i), kinds));
    const d = simplifyForDrawing(c, 0.01);
    // By hand: the start, the rapid's end, and each row's two ends.
    expect([...d.index]).toEqual([0, 1, 11, 12, 22, 23, 33]);
    expect([...d.kinds]).toEqual([KIND_START, KIND_RAPID, KIND_FEED, KIND_FEED, KIND_FEED, KIND_FEED, KIND_FEED]);
    expect([...d.positions.slice(6, 9)]).toEqual([10, 0, 0]);
  });

  it('keeps a turn back along the same line', () => {
    const pts: [number, number, number][] = [[0, 0, 0], [5, 0, 0], [10, 0, 0], [4, 0, 0], [2, 0, 0]];
    const c = decodePreview(encode(pts, [0, 1, 1, 2, 2], [KIND_START, KIND_FEED, KIND_FEED, KIND_FEED, KIND_FEED]));
    expect([...simplifyForDrawing(c, 0.01).index]).toEqual([0, 2, 4]);
  });

  it('leaves every point of a curve within the tolerance of the drawn segment over it', () => {
    // 20 000 chords of an Archimedean spiral (r from 1 to 40 mm): the drawn path has far
    // fewer points, and each chain point lies within the tolerance (plus float rounding)
    // of the drawn segment whose index range holds it.
    const pts: [number, number, number][] = [];
    for (let i = 0; i < 20_000; i++) {
      const th = i * 0.01;
      const r = 1 + (39 * i) / 20_000;
      pts.push([r * Math.cos(th), r * Math.sin(th), -0.0001 * i]);
    }
    const kinds = pts.map((_, i) => (i === 0 ? KIND_START : KIND_FEED));
    const c = decodePreview(encode(pts, pts.map(() => 1), kinds));
    const tol = 0.05;
    const d = simplifyForDrawing(c, tol);
    expect(d.count).toBeLessThan(c.count / 5);
    expect(d.index[0]).toBe(0);
    expect(d.index[d.count - 1]).toBe(c.count - 1);
    const at = (i: number) => [c.positions[3 * i], c.positions[3 * i + 1], c.positions[3 * i + 2]];
    let worst = 0;
    for (let q = 1; q < d.count; q++) {
      for (let i = d.index[q - 1]; i <= d.index[q]; i++) {
        worst = Math.max(worst, toSegment(at(i), at(d.index[q - 1]), at(d.index[q])));
      }
    }
    expect(worst).toBeLessThan(tol * 1.5);
  });
});
