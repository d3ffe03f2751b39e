//! The One Euro filter (Casiez, Roussel, Vogel, CHI 2012): a low-pass whose cutoff rises with speed.

/// Parameters of the One Euro filter; speeds are in target units per second.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OneEuroSettings {
    /// Cutoff frequency (Hz) at rest: lower removes more jitter, adds more lag.
    pub min_cutoff: f32,
    /// How fast the cutoff rises with speed (1 / target unit): higher cuts lag in fast motion.
    pub beta: f32,
    /// Cutoff (Hz) of the low-pass on the derivative.
    pub derivative_cutoff: f32,
}

impl Default for OneEuroSettings {
    fn default() -> Self {
        Self {
            min_cutoff: 3.0,
            beta: 0.5,
            derivative_cutoff: 1.0,
        }
    }
}

/// State of one filtered scalar.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OneEuro {
    pub(crate) value: f32,
    pub(crate) derivative: f32,
    pub(crate) primed: bool,
}

/// The filter's constants for one sample interval `dt`, shared by every scalar filtered over
/// that interval (so computed once per frame, not once per scalar): `1 / dt`, the derivative's
/// smoothing factor and `2 pi dt`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OneEuroStep {
    /// `1 / dt`.
    inv_dt: f32,
    /// The derivative low-pass's smoothing factor at this interval.
    derivative_alpha: f32,
    /// `2 pi dt`: a cutoff `c` (Hz) gives the smoothing factor of `2 pi c dt`.
    two_pi_dt: f32,
    /// `dt` is positive and finite (else every sample passes through and restarts the filter).
    valid: bool,
}

impl OneEuroStep {
    /// The constants of settings `s` for samples `dt` seconds apart.
    pub fn new(s: &OneEuroSettings, dt: f32) -> Self {
        let two_pi_dt = 2.0 * std::f32::consts::PI * dt;
        Self {
            inv_dt: 1.0 / dt,
            derivative_alpha: smoothing(s.derivative_cutoff * two_pi_dt),
            two_pi_dt,
            valid: dt > 0.0 && dt.is_finite(),
        }
    }
}

/// The low-pass smoothing factor `1 / (1 + tau / dt)`, `tau = 1 / (2 pi cutoff)`, from
/// `r = 2 pi cutoff dt`: `1 - 1 / (1 + r)`, one division (0 at `r = 0`, 1 as `r` grows without
/// bound).
fn smoothing(r: f32) -> f32 {
    1.0 - 1.0 / (1.0 + r)
}

impl OneEuro {
    /// Filters sample `x` taken `dt` seconds after the previous one; returns the filtered value.
    pub fn filter(&mut self, s: &OneEuroSettings, x: f32, dt: f32) -> f32 {
        self.filter_step(s, &OneEuroStep::new(s, dt), x)
    }

    /// [`OneEuro::filter`] with the interval's constants computed once ([`OneEuroStep::new`] of
    /// the same settings), for filtering many scalars over the same interval.
    pub fn filter_step(&mut self, s: &OneEuroSettings, step: &OneEuroStep, x: f32) -> f32 {
        if !self.primed || !step.valid {
            self.value = x;
            self.derivative = 0.0;
            self.primed = true;
            return x;
        }
        let dx = (x - self.value) * step.inv_dt;
        self.derivative += step.derivative_alpha * (dx - self.derivative);
        let cutoff = s.min_cutoff + s.beta * self.derivative.abs();
        let a = smoothing(cutoff * step.two_pi_dt);
        self.value += a * (x - self.value);
        self.value
    }

    /// Forgets the history: the next sample passes through unchanged.
    pub fn reset(&mut self) {
        self.primed = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_passes_and_noise_shrinks() {
        let s = OneEuroSettings::default();
        let mut f = OneEuro::default();
        for _ in 0..10 {
            assert_eq!(f.filter(&s, 2.5, 1.0 / 30.0), 2.5);
        }
        // Alternating +-1 noise at 30 Hz: a 3 Hz low-pass passes at most
        // alpha / (2 - alpha) of it in steady state (alpha = smoothing(cutoff, dt) < 0.4 here).
        let mut f = OneEuro::default();
        let mut last = 0.0f32;
        for k in 0..200 {
            let x = if k % 2 == 0 { 1.0 } else { -1.0 };
            last = f.filter(&s, x, 1.0 / 30.0);
        }
        assert!(last.abs() < 0.6, "{last}");
    }

    /// The filter as the paper writes it, in f64: `tau = 1 / (2 pi fc)`,
    /// `alpha = 1 / (1 + tau / dt)`.
    fn textbook(s: &OneEuroSettings, xs: &[f64], dt: f64) -> Vec<f64> {
        let alpha = |fc: f64| 1.0 / (1.0 + 1.0 / (2.0 * std::f64::consts::PI * fc) / dt);
        let (mut v, mut dv) = (xs[0], 0.0);
        let mut out = vec![v];
        for &x in &xs[1..] {
            dv += alpha(s.derivative_cutoff as f64) * ((x - v) / dt - dv);
            v += alpha(s.min_cutoff as f64 + s.beta as f64 * dv.abs()) * (x - v);
            out.push(v);
        }
        out
    }

    #[test]
    fn matches_the_textbook_form() {
        let s = OneEuroSettings::default();
        let dt = 1.0f32 / 30.0;
        // A random walk with jumps, as a tracked coordinate (cm).
        let mut seed = 3u64;
        let mut x = 0.0f64;
        let xs: Vec<f64> = (0..300)
            .map(|k| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                x += ((seed >> 40) as f64 / (1u64 << 24) as f64 - 0.5)
                    * if k % 50 == 0 { 4.0 } else { 0.2 };
                x
            })
            .collect();
        let want = textbook(&s, &xs, dt as f64);
        let mut f = OneEuro::default();
        let step = OneEuroStep::new(&s, dt);
        let scale = xs.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        // Each step rounds its few operations (within 8 eps of `scale`, the input's own f32
        // rounding and alpha's included) and the filter shrinks earlier errors by
        // 1 - alpha <= 1 - alpha(min_cutoff): the error stays below
        // 8 eps scale / alpha(min_cutoff).
        let a_min =
            1.0 / (1.0 + 1.0 / (2.0 * std::f64::consts::PI * s.min_cutoff as f64) / dt as f64);
        let tol = 8.0 * f32::EPSILON as f64 * scale / a_min;
        for (k, (&x, &w)) in xs.iter().zip(&want).enumerate() {
            let got = f.filter_step(&s, &step, x as f32) as f64;
            assert!(
                (got - w).abs() <= tol,
                "sample {k}: {got} vs {w} (tol {tol:e})"
            );
        }
    }

    #[test]
    fn follows_a_step_eventually() {
        let s = OneEuroSettings::default();
        let mut f = OneEuro::default();
        f.filter(&s, 0.0, 0.033);
        let mut y = 0.0;
        for _ in 0..60 {
            y = f.filter(&s, 1.0, 1.0 / 30.0);
        }
        // After 2 s at >= 3 Hz cutoff the residual is below (1 - alpha)^60 ~ 1e-13.
        assert!((y - 1.0).abs() < 1e-4, "{y}");
    }
}
