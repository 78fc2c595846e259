//! The recording of a run as CSV files (`setpoints.csv`: time, cycle, line, path speed,
//! axis and joint set-points; `feedback.csv`: joint feedback and following error), one row
//! per servo period; `rtcnc sim --out` and `rtcnc run --out` write the same files, so two
//! runs of a program compare column by column.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::Path;

use anyhow::Context as _;
use rtcnc_kernel::{MachineConfig, Sample};

/// The CSV files, written row by row into buffers that go to the files in large pieces; the
/// numbers are formatted by `decimal` (the standard formatter's text, several times
/// faster), so that recording every period stays a small part of a run.
pub struct SampleCsv {
    setpoints: std::fs::File,
    feedback: std::fs::File,
    setpoints_buf: Vec<u8>,
    feedback_buf: Vec<u8>,
    axes: Vec<usize>,
}

/// Bytes gathered before a write to a CSV file.
const CSV_CHUNK: usize = 1 << 16;

impl SampleCsv {
    /// Creates `setpoints.csv` and `feedback.csv` in `dir`.
    pub fn create(dir: &Path, config: &MachineConfig) -> anyhow::Result<SampleCsv> {
        std::fs::create_dir_all(dir).with_context(|| format!("{}", dir.display()))?;
        let open = |name: &str| -> anyhow::Result<std::fs::File> {
            let path = dir.join(name);
            std::fs::File::create(&path).with_context(|| format!("{}", path.display()))
        };
        let setpoints = open("setpoints.csv")?;
        let feedback = open("feedback.csv")?;
        let mut head = String::from("time_s,cycle,line,path_speed");
        for p in config.axis_plan() {
            let _ = write!(head, ",{}", p.axis.letter());
        }
        for j in &config.joints {
            let _ = write!(head, ",{}_setpoint", j.name);
        }
        head.push('\n');
        let mut setpoints_buf = Vec::with_capacity(2 * CSV_CHUNK);
        setpoints_buf.extend_from_slice(head.as_bytes());
        let mut head = String::from("time_s,cycle");
        for j in &config.joints {
            let _ = write!(head, ",{}_feedback,{}_following_error", j.name, j.name);
        }
        head.push('\n');
        let mut feedback_buf = Vec::with_capacity(2 * CSV_CHUNK);
        feedback_buf.extend_from_slice(head.as_bytes());
        Ok(SampleCsv {
            setpoints,
            feedback,
            setpoints_buf,
            feedback_buf,
            axes: config.axis_plan().iter().map(|p| p.axis as usize).collect(),
        })
    }

    /// One servo period's row in each file.
    pub fn write(&mut self, s: &Sample, joints: usize) -> std::io::Result<()> {
        use crate::decimal::{push_fixed, push_u64};
        let t = s.time_ns as f64 * 1e-9;
        let out = &mut self.setpoints_buf;
        push_fixed(out, t, 6);
        out.push(b',');
        push_u64(out, s.cycle);
        out.push(b',');
        push_u64(out, u64::from(s.line));
        out.push(b',');
        push_fixed(out, s.path_speed, 6);
        for &i in &self.axes {
            out.push(b',');
            push_fixed(out, s.axes[i], 6);
        }
        for j in 0..joints {
            out.push(b',');
            push_fixed(out, s.setpoint[j], 6);
        }
        out.push(b'\n');
        let out = &mut self.feedback_buf;
        push_fixed(out, t, 6);
        out.push(b',');
        push_u64(out, s.cycle);
        for j in 0..joints {
            out.push(b',');
            push_fixed(out, s.feedback[j], 6);
            out.push(b',');
            push_fixed(out, s.following_error[j], 7);
        }
        out.push(b'\n');
        if self.setpoints_buf.len() >= CSV_CHUNK {
            self.setpoints.write_all(&self.setpoints_buf)?;
            self.setpoints_buf.clear();
        }
        if self.feedback_buf.len() >= CSV_CHUNK {
            self.feedback.write_all(&self.feedback_buf)?;
            self.feedback_buf.clear();
        }
        Ok(())
    }

    /// Writes what is buffered.
    pub fn finish(mut self) -> anyhow::Result<()> {
        self.setpoints.write_all(&self.setpoints_buf)?;
        self.feedback.write_all(&self.feedback_buf)?;
        self.setpoints.flush()?;
        self.feedback.flush()?;
        Ok(())
    }
}
