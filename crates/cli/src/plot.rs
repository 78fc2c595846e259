//! `rtcnc sim`'s `plot.svg`: the tool path as run (the axis set-points) seen from the top and
//! from the front, rapids and feeds in their colours as in the HMI, and the path speed over
//! time; every panel with ticks and units. Hand-written SVG (no plotting library).

use std::collections::HashMap;
use std::fmt::Write as _;

use rtcnc_kernel::Sample;

/// Most points the plot keeps: once twice this many are gathered, every other one goes and
/// only every other servo period is taken from then on, so memory stays bounded however
/// long the program runs.
pub const PLOT_POINTS: usize = 20_000;

/// How a program line moves, from the interpreter's canonical output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineKind {
    Rapid,
    Feed,
}

/// One kept servo period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlotPoint {
    /// Time, s.
    pub t: f64,
    /// X, Y, Z set-points, machine coordinates.
    pub xyz: [f64; 3],
    /// Path speed, units/s.
    pub speed: f64,
    /// Program line.
    pub line: u32,
}

pub struct PlotData {
    pub points: Vec<PlotPoint>,
    /// A point is kept every `stride` samples.
    pub stride: u64,
    samples: u64,
}

impl Default for PlotData {
    fn default() -> Self {
        PlotData {
            points: Vec::with_capacity(2 * PLOT_POINTS),
            stride: 1,
            samples: 0,
        }
    }
}

const RAPID: &str = "#e65100";
const FEED: &str = "#1565c0";

impl PlotData {
    pub fn add(&mut self, s: &Sample) {
        let keep = self.samples % self.stride == 0;
        self.samples += 1;
        if !keep {
            return;
        }
        self.points.push(PlotPoint {
            t: s.time_ns as f64 * 1e-9,
            xyz: [s.axes[0], s.axes[1], s.axes[2]],
            speed: s.path_speed,
            line: s.line,
        });
        if self.points.len() >= 2 * PLOT_POINTS {
            let mut i = 0;
            self.points.retain(|_| {
                i += 1;
                i % 2 == 1
            });
            self.stride *= 2;
        }
    }

    /// The plot. `kinds` says which program lines are rapids (a line that also feeds, as a
    /// canned cycle, is drawn as a feed); `lathe` draws Z across and X up, in one view.
    pub fn svg(&self, kinds: &HashMap<u32, LineKind>, lathe: bool) -> String {
        let (w, h) = (1100.0, 860.0);
        let mut out = String::new();
        let _ = writeln!(
            out,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">
<rect width="{w}" height="{h}" fill="white"/>"#
        );
        let rapid = |p: &PlotPoint| kinds.get(&p.line) == Some(&LineKind::Rapid);
        let path = |a: usize, b: usize| -> Vec<(f64, f64, bool)> {
            self.points
                .iter()
                .map(|p| (p.xyz[a], p.xyz[b], rapid(p)))
                .collect()
        };
        if lathe {
            let frame = Frame::new(70.0, 40.0, 560.0, 760.0, &path(2, 0), true);
            frame.draw(&mut out, "tool path (Z across, X up)", "Z (mm)", "X (mm)");
            frame.path(&mut out, &path(2, 0));
        } else {
            let top = Frame::new(70.0, 40.0, 560.0, 430.0, &path(0, 1), true);
            top.draw(&mut out, "top (X-Y)", "X (mm)", "Y (mm)");
            top.path(&mut out, &path(0, 1));
            let front = Frame::new(70.0, 550.0, 560.0, 250.0, &path(0, 2), true);
            front.draw(&mut out, "front (X-Z)", "X (mm)", "Z (mm)");
            front.path(&mut out, &path(0, 2));
        }
        let speed: Vec<(f64, f64, bool)> = self
            .points
            .iter()
            .map(|p| (p.t, p.speed, rapid(p)))
            .collect();
        let v = Frame::new(720.0, 40.0, 350.0, 430.0, &speed, false);
        v.draw(
            &mut out,
            "path speed over time",
            "time (s)",
            "path speed (mm/s)",
        );
        v.path(&mut out, &speed);
        // Legend.
        let _ = writeln!(
            out,
            r##"<g font-size="13"><line x1="720" y1="560" x2="760" y2="560" stroke="{FEED}" stroke-width="2"/><text x="768" y="564">feed (G1, G2, G3, cycles)</text>
<line x1="720" y1="584" x2="760" y2="584" stroke="{RAPID}" stroke-width="2" stroke-dasharray="6 4"/><text x="768" y="588">rapid (G0)</text>
<text x="720" y="616" fill="#555">the axis set-points as run, machine coordinates</text></g>"##
        );
        out.push_str("</svg>\n");
        out
    }
}

/// A panel: where it is on the page and the data range it shows.
struct Frame {
    x0: f64,
    y0: f64,
    w: f64,
    h: f64,
    min: (f64, f64),
    max: (f64, f64),
}

impl Frame {
    /// The range of `pts` with nice ends; `equal` keeps one scale on both axes (a path).
    fn new(x0: f64, y0: f64, w: f64, h: f64, pts: &[(f64, f64, bool)], equal: bool) -> Frame {
        let (mut xmin, mut xmax, mut ymin, mut ymax) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for p in pts.iter().filter(|p| p.0.is_finite() && p.1.is_finite()) {
            xmin = xmin.min(p.0);
            xmax = xmax.max(p.0);
            ymin = ymin.min(p.1);
            ymax = ymax.max(p.1);
        }
        if xmin > xmax {
            (xmin, xmax, ymin, ymax) = (0.0, 1.0, 0.0, 1.0);
        }
        let (xmin, xmax) = nice_range(xmin, xmax);
        let (mut ymin, mut ymax) = nice_range(ymin, ymax);
        let (mut xmin, mut xmax) = (xmin, xmax);
        if equal {
            // One scale: the shorter side's range grows around its middle.
            let s = (w / (xmax - xmin)).min(h / (ymax - ymin));
            let (xs, ys) = (w / s, h / s);
            let (xc, yc) = ((xmin + xmax) / 2.0, (ymin + ymax) / 2.0);
            (xmin, xmax) = (xc - xs / 2.0, xc + xs / 2.0);
            (ymin, ymax) = (yc - ys / 2.0, yc + ys / 2.0);
        }
        Frame {
            x0,
            y0,
            w,
            h,
            min: (xmin, ymin),
            max: (xmax, ymax),
        }
    }

    fn px(&self, x: f64, y: f64) -> (f64, f64) {
        (
            self.x0 + (x - self.min.0) / (self.max.0 - self.min.0) * self.w,
            self.y0 + self.h - (y - self.min.1) / (self.max.1 - self.min.1) * self.h,
        )
    }

    /// Box, grid, ticks with their values, title and axis names.
    fn draw(&self, out: &mut String, title: &str, x_name: &str, y_name: &str) {
        let (x0, y0, w, h) = (self.x0, self.y0, self.w, self.h);
        let _ = writeln!(
            out,
            r##"<g><rect x="{x0}" y="{y0}" width="{w}" height="{h}" fill="none" stroke="#888"/>
<text x="{}" y="{}" text-anchor="middle" font-weight="bold" font-size="14">{title}</text>
<text x="{}" y="{}" text-anchor="middle">{x_name}</text>
<text x="{}" y="{}" text-anchor="middle" transform="rotate(-90 {} {})">{y_name}</text>"##,
            x0 + w / 2.0,
            y0 - 12.0,
            x0 + w / 2.0,
            y0 + h + 38.0,
            x0 - 52.0,
            y0 + h / 2.0,
            x0 - 52.0,
            y0 + h / 2.0,
        );
        for t in ticks(self.min.0, self.max.0) {
            let (x, _) = self.px(t, self.min.1);
            let _ = writeln!(
                out,
                r##"<line x1="{x:.1}" y1="{y0}" x2="{x:.1}" y2="{}" stroke="#e4e4e4"/><line x1="{x:.1}" y1="{}" x2="{x:.1}" y2="{}" stroke="#888"/><text x="{x:.1}" y="{}" text-anchor="middle">{}</text>"##,
                y0 + h,
                y0 + h,
                y0 + h + 5.0,
                y0 + h + 18.0,
                tick_label(t)
            );
        }
        for t in ticks(self.min.1, self.max.1) {
            let (_, y) = self.px(self.min.0, t);
            let _ = writeln!(
                out,
                r##"<line x1="{x0}" y1="{y:.1}" x2="{}" y2="{y:.1}" stroke="#e4e4e4"/><line x1="{}" y1="{y:.1}" x2="{x0}" y2="{y:.1}" stroke="#888"/><text x="{}" y="{:.1}" text-anchor="end">{}</text>"##,
                x0 + w,
                x0 - 5.0,
                x0 - 8.0,
                y + 4.0,
                tick_label(t)
            );
        }
        out.push_str("</g>\n");
    }

    /// The points as polylines, one per run of rapids or feeds.
    fn path(&self, out: &mut String, pts: &[(f64, f64, bool)]) {
        let mut i = 0;
        while i < pts.len() {
            let rapid = pts[i].2;
            let mut j = i;
            while j + 1 < pts.len() && pts[j + 1].2 == rapid {
                j += 1;
            }
            // Each run starts where the one before ended, so the path has no gaps.
            let from = i.saturating_sub(1);
            let (stroke, dash) = if rapid {
                (RAPID, r#" stroke-dasharray="6 4""#)
            } else {
                (FEED, "")
            };
            let _ = write!(
                out,
                r#"<polyline fill="none" stroke="{stroke}" stroke-width="1.2"{dash} points=""#
            );
            for p in &pts[from..=j] {
                if p.0.is_finite() && p.1.is_finite() {
                    let (x, y) = self.px(p.0, p.1);
                    let _ = write!(out, "{x:.2},{y:.2} ");
                }
            }
            out.push_str("\"/>\n");
            i = j + 1;
        }
    }
}

/// A tick step of 1, 2 or 5 × 10ⁿ giving about five to ten ticks over `span`.
pub fn tick_step(span: f64) -> f64 {
    if !(span.is_finite() && span > 0.0) {
        return 1.0;
    }
    let raw = span / 6.0;
    let p = 10f64.powf(raw.log10().floor());
    let m = raw / p;
    p * if m < 1.5 {
        1.0
    } else if m < 3.5 {
        2.0
    } else if m < 7.5 {
        5.0
    } else {
        10.0
    }
}

/// The range widened to whole tick steps (a flat range gets one unit around it).
pub fn nice_range(min: f64, max: f64) -> (f64, f64) {
    let (min, max) = if max - min < 1e-9 {
        (min - 0.5, max + 0.5)
    } else {
        (min, max)
    };
    let s = tick_step(max - min);
    ((min / s).floor() * s, (max / s).ceil() * s)
}

/// The tick values within [min, max], on whole multiples of the step.
pub fn ticks(min: f64, max: f64) -> Vec<f64> {
    let s = tick_step(max - min);
    let first = (min / s - 1e-9).ceil() as i64;
    let last = (max / s + 1e-9).floor() as i64;
    (first..=last.min(first + 100))
        .map(|k| k as f64 * s)
        .collect()
}

fn tick_label(v: f64) -> String {
    let s = format!("{:.3}", v);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(cycle: u64, x: f64, line: u32) -> Sample {
        Sample {
            time_ns: cycle * 1_000_000,
            cycle,
            setpoint: [0.0; 16],
            feedback: [0.0; 16],
            following_error: [0.0; 16],
            axes: [x, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            line,
            path_speed: 0.0,
        }
    }

    #[test]
    fn the_plot_keeps_a_bounded_number_of_evenly_spaced_points() {
        let mut plot = PlotData::default();
        // An hour of 1 ms periods.
        for cycle in 0..3_600_000 {
            plot.add(&sample(cycle, 0.0, 0));
        }
        assert!(plot.points.len() < 2 * PLOT_POINTS, "{}", plot.points.len());
        assert!(plot.points.len() >= PLOT_POINTS / 2);
        // Evenly spaced: every kept point is `stride` periods after the one before.
        let step = plot.points[1].t - plot.points[0].t;
        assert!((step - plot.stride as f64 * 1e-3).abs() < 1e-9);
        for w in plot.points.windows(2) {
            assert!((w[1].t - w[0].t - step).abs() < 1e-6);
        }
        assert_eq!(plot.points[0].t, 0.0);
    }

    #[test]
    fn ticks_fall_on_one_two_five_steps() {
        // Hand-checked: 0..63 mm in steps of 10, 0..0.9 in steps of 0.1 (0.15 rounds to
        // 1 × 0.1), -3..5 in steps of 1 (8/6 = 1.33).
        assert_eq!(nice_range(0.0, 63.0), (0.0, 70.0));
        assert_eq!(
            ticks(0.0, 70.0),
            vec![0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0]
        );
        assert_eq!(tick_step(0.9), 0.1);
        assert_eq!(ticks(-3.0, 5.0).len(), 9);
        assert_eq!(tick_step(250.0), 50.0);
        assert_eq!(tick_label(-0.0), "0");
        assert_eq!(tick_label(2.5), "2.5");
        assert_eq!(tick_label(40.0), "40");
    }

    #[test]
    fn rapids_and_feeds_are_drawn_in_their_own_colours_and_the_path_has_no_gaps() {
        let mut plot = PlotData::default();
        // Line 1 a rapid from X0 to X10, line 2 a feed on to X20.
        for c in 0..=10 {
            plot.add(&sample(c, c as f64, 1));
        }
        for c in 11..=20 {
            plot.add(&sample(c, c as f64, 2));
        }
        let kinds = HashMap::from([(1, LineKind::Rapid), (2, LineKind::Feed)]);
        let svg = plot.svg(&kinds, false);
        // Top, front, speed: each view has one rapid run and one feed run.
        assert_eq!(
            svg.matches(&format!(r#"stroke="{RAPID}" stroke-width="1.2""#))
                .count(),
            3
        );
        assert_eq!(
            svg.matches(&format!(r#"stroke="{FEED}" stroke-width="1.2""#))
                .count(),
            3
        );
        for name in [
            "top (X-Y)",
            "front (X-Z)",
            "X (mm)",
            "Z (mm)",
            "path speed (mm/s)",
            "time (s)",
        ] {
            assert!(svg.contains(name), "{name}");
        }
        // The feed run starts at the rapid's last point (X10) in the top view: its first
        // point is the rapid polyline's last.
        let polylines: Vec<&str> = svg
            .split("points=\"")
            .skip(1)
            .map(|s| s.split('"').next().unwrap())
            .collect();
        let rapid_last = polylines[0].split_whitespace().last().unwrap();
        let feed_first = polylines[1].split_whitespace().next().unwrap();
        assert_eq!(rapid_last, feed_first);
    }
}
