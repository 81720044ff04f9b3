//! Goodness-of-fit measures shared by host tools and tests.

/// Gauge pressure below which samples are left out of [`nmse_pct`], bar g.
pub const NMSE_MIN_BAR_G: f64 = 0.2;

/// NMSE of SPEC §6, Eq. (16): `100 % · sqrt(mean(((P − P̂)/P)²))` over the samples where the
/// measured gauge pressure `P` exceeds [`NMSE_MIN_BAR_G`] (the paper divides by P and does not
/// say how it avoids P = 0; the first samples of every release are at 0 bar g).
///
/// Pressures are gauge, bar. Returns `None` when no sample qualifies or the slices differ in
/// length.
pub fn nmse_pct(measured: &[f64], model: &[f64]) -> Option<f64> {
    if measured.len() != model.len() {
        return None;
    }
    let mut acc = Nmse::new();
    for (&p, &q) in measured.iter().zip(model) {
        acc.push(p, q);
    }
    acc.pct()
}

/// [`nmse_pct`] one sample at a time (a replay of any length in constant memory); the same
/// sums in the same order, so the same result.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Nmse {
    sum: f64,
    n: u32,
}

impl Nmse {
    /// No sample yet.
    pub const fn new() -> Self {
        Self { sum: 0.0, n: 0 }
    }

    /// Adds a measured gauge pressure `p` and the model's `q` (bar).
    pub fn push(&mut self, p: f64, q: f64) {
        if p > NMSE_MIN_BAR_G {
            let e = (p - q) / p;
            self.sum += e * e;
            self.n = self.n.saturating_add(1);
        }
    }

    /// The NMSE so far, %; `None` while no sample qualifies.
    pub fn pct(&self) -> Option<f64> {
        (self.n > 0).then(|| 100.0 * libm::sqrt(self.sum / f64::from(self.n)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nmse_known_values() {
        assert_eq!(nmse_pct(&[1.0, 2.0], &[1.0, 2.0]), Some(0.0));
        let v = nmse_pct(&[0.0, 1.0, 2.0], &[5.0, 1.1, 2.2]).unwrap();
        assert!((v - 10.0).abs() < 1e-9);
        assert_eq!(nmse_pct(&[0.1], &[0.0]), None);
        assert_eq!(nmse_pct(&[1.0], &[]), None);
    }
}
