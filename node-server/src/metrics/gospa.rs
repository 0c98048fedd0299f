//! GOSPA (Rahmathullah, García-Fernández & Svensson 2017) as Stone Soup's `GOSPAMetric`
//! computes it with α = 2: per frame, an optimal assignment of truths to hypotheses that
//! minimises the sum of min(d, c)^p, where a pair at distance ≥ c counts as one missed and one
//! false target at c^p/2 each; GOSPA = (localisation + missed + false)^(1/p).
//!
//! Stone Soup scores only the times at which some truth or hypothesis exists, so frames with
//! neither are left out of the average here too. Its components are reported in its units:
//! localisation is the sum of matched distances to the p, missed and false are c^p/2 per target.

use assign::max_weight_matching;

/// Running sums over frames.
#[derive(Debug)]
pub(super) struct Gospa {
    c: f64,
    p: f64,
    frames: usize,
    distance: f64,
    localisation: f64,
    missed: f64,
    false_: f64,
}

/// Averages over the scored frames (all zero when none was scored).
#[derive(Debug)]
pub(super) struct GospaMeans {
    pub frames: usize,
    pub distance: f64,
    pub localisation: f64,
    pub missed: f64,
    pub false_: f64,
}

/// One frame's GOSPA: (distance, localisation, missed, false).
pub(super) fn frame_gospa(nt: usize, nh: usize, d: &[f64], c: f64, p: f64) -> (f64, f64, f64, f64) {
    let cp = c.powf(p);
    // Maximise the saving c^p − d^p of each pair closer than c over leaving both unassigned.
    let pairs = max_weight_matching(nt, nh, cp, false, |i, j| {
        let dist = d[i * nh + j];
        (dist < c).then(|| cp - dist.powf(p))
    });
    let mut localisation = 0.0;
    let mut assigned = 0;
    for (i, j) in pairs.into_iter().enumerate() {
        if let Some(j) = j {
            localisation += d[i * nh + j].powf(p);
            assigned += 1;
        }
    }
    let missed = cp / 2.0 * (nt - assigned) as f64;
    let false_ = cp / 2.0 * (nh - assigned) as f64;
    (
        (localisation + missed + false_).powf(1.0 / p),
        localisation,
        missed,
        false_,
    )
}

impl Gospa {
    pub fn new(c: f64, p: f64) -> Self {
        Gospa {
            c,
            p,
            frames: 0,
            distance: 0.0,
            localisation: 0.0,
            missed: 0.0,
            false_: 0.0,
        }
    }

    /// Adds one frame with `nt` truths and `nh` hypotheses; `d` is its truth-major distance
    /// matrix.
    pub fn frame(&mut self, nt: usize, nh: usize, d: &[f64]) {
        if nt + nh == 0 {
            return;
        }
        let (distance, localisation, missed, false_) = frame_gospa(nt, nh, d, self.c, self.p);
        self.frames += 1;
        self.distance += distance;
        self.localisation += localisation;
        self.missed += missed;
        self.false_ += false_;
    }

    pub fn finish(self) -> GospaMeans {
        let n = self.frames.max(1) as f64;
        GospaMeans {
            frames: self.frames,
            distance: self.distance / n,
            localisation: self.localisation / n,
            missed: self.missed / n,
            false_: self.false_ / n,
        }
    }
}
