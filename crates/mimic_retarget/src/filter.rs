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

fn smoothing(cutoff: f32, dt: f32) -> f32 {
    let tau = 1.0 / (2.0 * std::f32::consts::PI * cutoff);
    1.0 / (1.0 + tau / dt)
}

impl OneEuro {
    /// Filters sample `x` taken `dt` seconds after the previous one; returns the filtered value.
    pub fn filter(&mut self, s: &OneEuroSettings, x: f32, dt: f32) -> f32 {
        if !self.primed || dt <= 0.0 || !dt.is_finite() {
            self.value = x;
            self.derivative = 0.0;
            self.primed = true;
            return x;
        }
        let dx = (x - self.value) / dt;
        let a_d = smoothing(s.derivative_cutoff, dt);
        self.derivative += a_d * (dx - self.derivative);
        let cutoff = s.min_cutoff + s.beta * self.derivative.abs();
        let a = smoothing(cutoff, dt);
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
