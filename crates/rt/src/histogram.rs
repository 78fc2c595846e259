//! Fixed-size histograms: recording never allocates, and a reader on another thread can
//! take a snapshot at any time (counters are atomics written by one thread).

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

/// Adds to a counter that has one writer: a plain load and store, no locked instruction.
#[inline]
pub(crate) fn bump(counter: &AtomicU64, by: u64) {
    counter.store(counter.load(Relaxed).wrapping_add(by), Relaxed);
}

/// Values below this are counted exactly, one bucket per nanosecond.
const EXACT: u64 = 64;
/// Sub-buckets per power of two above `EXACT`: relative bucket width at most 1/32.
const SUB_BITS: u32 = 5;
const SUB: usize = 1 << SUB_BITS;
/// Largest power of two covered (2^40 ns is about 18 minutes); larger values land in the last bucket.
const MAX_EXP: u32 = 40;
const BUCKETS: usize = EXACT as usize + (MAX_EXP as usize - 6 + 1) * SUB;

/// A log-linear histogram of nanosecond values (exact below 64 ns, then 32 buckets per
/// octave, so a percentile read from it is at most about 3 % high), with exact count, sum,
/// minimum and maximum.
pub struct LogHistogram {
    buckets: Box<[AtomicU64]>,
    count: AtomicU64,
    sum: AtomicU64,
    min: AtomicU64,
    max: AtomicU64,
}

fn bucket_of(value: u64) -> usize {
    if value < EXACT {
        return value as usize;
    }
    let exp = (63 - value.leading_zeros()).min(MAX_EXP);
    if exp == MAX_EXP && value >= (1u64 << (MAX_EXP + 1)) {
        return BUCKETS - 1;
    }
    let sub = ((value >> (exp - SUB_BITS)) as usize) & (SUB - 1);
    EXACT as usize + (exp as usize - 6) * SUB + sub
}

/// Largest value that falls into bucket `index`.
fn bucket_high(index: usize) -> u64 {
    if index < EXACT as usize {
        return index as u64;
    }
    let i = index - EXACT as usize;
    let exp = (i / SUB) as u32 + 6;
    let sub = (i % SUB) as u64;
    let low = (SUB as u64 + sub) << (exp - SUB_BITS);
    low + (1u64 << (exp - SUB_BITS)) - 1
}

impl Default for LogHistogram {
    fn default() -> Self {
        Self::new()
    }
}

impl LogHistogram {
    /// An empty histogram (about 9 KiB, allocated here once).
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new() -> Self {
        LogHistogram {
            buckets: (0..BUCKETS).map(|_| AtomicU64::new(0)).collect(),
            count: AtomicU64::new(0),
            sum: AtomicU64::new(0),
            min: AtomicU64::new(u64::MAX),
            max: AtomicU64::new(0),
        }
    }

    /// Adds one value (single writer; no allocation, no lock).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn record(&self, value: u64) {
        if let Some(b) = self.buckets.get(bucket_of(value)) {
            bump(b, 1);
        }
        bump(&self.count, 1);
        bump(&self.sum, value);
        if value < self.min.load(Relaxed) {
            self.min.store(value, Relaxed);
        }
        if value > self.max.load(Relaxed) {
            self.max.store(value, Relaxed);
        }
    }

    /// The non-empty buckets as (largest value of the bucket, count), in order.
    ///
    /// Real-time: no (allocates).
    pub fn buckets(&self) -> Vec<(u64, u64)> {
        self.buckets
            .iter()
            .enumerate()
            .map(|(i, b)| (bucket_high(i), b.load(Relaxed)))
            .filter(|&(_, n)| n > 0)
            .collect()
    }

    /// A summary of what was recorded.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn summary(&self) -> Summary {
        let count = self.count.load(Relaxed);
        if count == 0 {
            return Summary::default();
        }
        let max = self.max.load(Relaxed);
        let target = count - count / 100; // the smallest value with at least 99 % at or below it
        let mut seen = 0u64;
        let mut p99 = max;
        for (i, b) in self.buckets.iter().enumerate() {
            seen += b.load(Relaxed);
            if seen >= target {
                p99 = bucket_high(i).min(max);
                break;
            }
        }
        Summary {
            count,
            min: self.min.load(Relaxed),
            mean: self.sum.load(Relaxed) / count,
            p99,
            max,
        }
    }
}

/// Count, minimum, mean, 99th percentile and maximum of a histogram, in nanoseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Summary {
    /// Values recorded.
    pub count: u64,
    /// Smallest value.
    pub min: u64,
    /// Mean (rounded down).
    pub mean: u64,
    /// 99th percentile (bucket upper bound, never above `max`).
    pub p99: u64,
    /// Largest value.
    pub max: u64,
}

/// A histogram with equal-width bins and an overflow bin, like cyclictest's (1 µs bins):
/// percentiles are exact to the bin width.
pub struct LinearHistogram {
    bin_width: u64,
    bins: Box<[AtomicU64]>,
    overflow: AtomicU64,
    count: AtomicU64,
    sum: AtomicU64,
    min: AtomicU64,
    max: AtomicU64,
}

impl LinearHistogram {
    /// `bins` bins of `bin_width` nanoseconds each (allocated here once).
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new(bin_width: u64, bins: usize) -> Self {
        LinearHistogram {
            bin_width: bin_width.max(1),
            bins: (0..bins.max(1)).map(|_| AtomicU64::new(0)).collect(),
            overflow: AtomicU64::new(0),
            count: AtomicU64::new(0),
            sum: AtomicU64::new(0),
            min: AtomicU64::new(u64::MAX),
            max: AtomicU64::new(0),
        }
    }

    /// Adds one value (single writer; no allocation, no lock).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn record(&self, value: u64) {
        let index = value / self.bin_width;
        match usize::try_from(index).ok().and_then(|i| self.bins.get(i)) {
            Some(b) => bump(b, 1),
            None => bump(&self.overflow, 1),
        };
        bump(&self.count, 1);
        bump(&self.sum, value);
        if value < self.min.load(Relaxed) {
            self.min.store(value, Relaxed);
        }
        if value > self.max.load(Relaxed) {
            self.max.store(value, Relaxed);
        }
    }

    /// Width of one bin in nanoseconds.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn bin_width(&self) -> u64 {
        self.bin_width
    }

    /// The count of every bin, in order.
    ///
    /// Real-time: no (allocates).
    pub fn bins(&self) -> Vec<u64> {
        self.bins.iter().map(|b| b.load(Relaxed)).collect()
    }

    /// Values beyond the last bin.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn overflow(&self) -> u64 {
        self.overflow.load(Relaxed)
    }

    /// Count, min, mean, p99 (upper edge of the bin holding it, never above max) and max.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn summary(&self) -> Summary {
        let count = self.count.load(Relaxed);
        if count == 0 {
            return Summary::default();
        }
        let max = self.max.load(Relaxed);
        let target = count - count / 100;
        let mut seen = 0u64;
        let mut p99 = max;
        for (i, b) in self.bins.iter().enumerate() {
            seen += b.load(Relaxed);
            if seen >= target {
                p99 = ((i as u64 + 1) * self.bin_width - 1).min(max);
                break;
            }
        }
        Summary {
            count,
            min: self.min.load(Relaxed),
            mean: self.sum.load(Relaxed) / count,
            p99,
            max,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_buckets_cover_values_in_order() {
        let mut last = 0;
        for v in [
            0u64,
            1,
            63,
            64,
            65,
            100,
            1000,
            12_345,
            1 << 20,
            (1 << 40) - 1,
        ] {
            let b = bucket_of(v);
            assert!(b >= last, "bucket of {v}");
            assert!(bucket_high(b) >= v, "upper bound of bucket of {v}");
            last = b;
        }
        assert!(bucket_of(u64::MAX) < BUCKETS);
    }

    #[test]
    fn log_summary_of_known_values() {
        let h = LogHistogram::new();
        for v in 1..=100u64 {
            h.record(v * 1000);
        }
        let s = h.summary();
        assert_eq!(
            (s.count, s.min, s.mean, s.max),
            (100, 1000, 50_500, 100_000)
        );
        // the 99th of 100 values is 99 000; its bucket is at most 1/32 wide
        assert!(
            s.p99 >= 99_000 && s.p99 <= 99_000 + 99_000 / 32,
            "p99 {}",
            s.p99
        );
    }

    #[test]
    fn linear_percentile_is_exact_to_the_bin() {
        let h = LinearHistogram::new(1000, 100);
        for v in 0..1000u64 {
            h.record(v * 10); // 0..9990 ns, 100 values per 1 µs bin
        }
        h.record(500_000); // overflow
        let s = h.summary();
        assert_eq!(s.count, 1001);
        assert_eq!(h.overflow(), 1);
        // 1001 values: at least 991 at or below p99 -> the 10th bin (9000..9999)
        assert_eq!(s.p99, 9999);
        assert_eq!(s.max, 500_000);
    }
}
