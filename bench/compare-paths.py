#!/usr/bin/env python3
"""Whether two recordings of a program (the setpoints.csv of `rtcnc sim --out` and of
`rtcnc run --out`) drive the axes along the same path, whatever their timing.

    bench/compare-paths.py REFERENCE_DIR RUN_DIR [TOLERANCE_MM]

Walks the run's axis set-points in order along the reference's polyline (each point's
distance to the nearest reference segment at or after the last match) and prints the largest
distance, the distance between the two end points, and how far along the reference the run
got. Exit status 0 when the largest distance and the end distance are within TOLERANCE_MM
(default 0.001) and the run reached the reference's end, 1 otherwise.
"""
import csv
import math
import sys

# Reference segments searched ahead of the last match: set-points are dense (one per
# period), so a matching point is never far ahead unless the run skipped a stretch.
WINDOW = 64


def axis_path(folder):
    with open(f"{folder}/setpoints.csv", newline="") as f:
        rows = csv.reader(f)
        head = next(rows)
        axes = [i for i, name in enumerate(head) if i >= 4 and not name.endswith("_setpoint")]
        path = []
        for row in rows:
            p = tuple(float(row[i]) for i in axes)
            if not path or p != path[-1]:
                path.append(p)
    return path


def segment_distance(p, a, b):
    ab = [y - x for x, y in zip(a, b)]
    ap = [y - x for x, y in zip(a, p)]
    length2 = sum(c * c for c in ab)
    t = 0.0 if length2 == 0.0 else max(0.0, min(1.0, sum(x * y for x, y in zip(ab, ap)) / length2))
    return math.dist(p, [x + t * c for x, c in zip(a, ab)])


def main():
    reference, run = axis_path(sys.argv[1]), axis_path(sys.argv[2])
    tolerance = float(sys.argv[3]) if len(sys.argv) > 3 else 0.001
    if len(reference) < 2 or not run:
        print("path        nothing to compare (a recording without motion)")
        return 1
    at, worst = 0, 0.0
    for p in run:
        best, best_at = math.inf, at
        for k in range(at, min(at + WINDOW, len(reference) - 1)):
            d = segment_distance(p, reference[k], reference[k + 1])
            if d < best:
                best, best_at = d, k
        at = best_at
        worst = max(worst, best)
    end = math.dist(run[-1], reference[-1])
    reached = at >= len(reference) - 1 - WINDOW
    print(
        f"path        largest distance {worst:.6f} mm, end {end:.6f} mm apart, "
        f"reached the reference's end: {'yes' if reached else 'no'}"
    )
    return 0 if worst <= tolerance and end <= tolerance and reached else 1


if __name__ == "__main__":
    sys.exit(main())
