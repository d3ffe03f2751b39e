//! Helpers shared by the workspace's tests and benches: reproducible pseudo-random numbers that
//! need no dependency and share no code with what they test, and named test threads.
//!
//! A dev-dependency only (`publish = false`): no library or binary of the workspace links it.

/// A 64-bit linear congruential generator (Knuth's MMIX constants), the one random source of the
/// tests: the state after each step is the output.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Lcg(pub u64);

impl Lcg {
    /// Multiplier of the recurrence `s' = A s + C (mod 2^64)`.
    pub const A: u64 = 6364136223846793005;
    /// Increment of the recurrence.
    pub const C: u64 = 1442695040888963407;

    /// A generator starting from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// Advances the state and returns it.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_mul(Self::A).wrapping_add(Self::C);
        self.0
    }

    /// Uniform in [-1, 1), from the top 24 bits of the state.
    pub fn next_f32(&mut self) -> f32 {
        ((self.next_u64() >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }

    /// Uniform in [-1, 1), from the top 53 bits of the state.
    pub fn next_f64(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// One [`Lcg::next_f32`] step on a bare state, for tests that thread a `&mut u64` seed.
pub fn lcg(seed: &mut u64) -> f32 {
    let mut g = Lcg(*seed);
    let v = g.next_f32();
    *seed = g.0;
    v
}

/// xorshift64* with Box-Muller normals: a noise source for tests that want a Gaussian.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct XorShift64Star(pub u64);

impl XorShift64Star {
    /// Uniform in (0, 1) (never 0, so `ln` is finite), 53 bits.
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// Standard normal (mean 0, variance 1), one Box-Muller draw from two uniforms.
    pub fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// Starts a thread named `name` (a test's threads are named too: the name is in a panic message).
///
/// # Panics
/// If the thread cannot be started.
pub fn spawn<T, F>(name: &str, f: F) -> std::thread::JoinHandle<T>
where
    T: Send + 'static,
    F: FnOnce() -> T + Send + 'static,
{
    std::thread::Builder::new()
        .name(name.to_owned())
        .spawn(f)
        .expect("start a test thread")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lcg_follows_its_recurrence_and_stays_in_range() {
        let mut g = Lcg::new(7);
        let first = g.next_u64();
        assert_eq!(first, 7u64.wrapping_mul(Lcg::A).wrapping_add(Lcg::C));
        let mut seed = 7u64;
        let mut h = Lcg::new(7);
        for _ in 0..10_000 {
            let a = lcg(&mut seed);
            assert_eq!(a, h.next_f32());
            assert!((-1.0..1.0).contains(&a), "{a}");
        }
        assert_eq!(seed, h.0);
        let mut g = Lcg::new(3);
        let v: Vec<f64> = (0..10_000).map(|_| g.next_f64()).collect();
        assert!(v.iter().all(|x| (-1.0..1.0).contains(x)));
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        assert!(mean.abs() < 0.05, "mean {mean}");
    }

    #[test]
    fn normals_have_unit_variance() {
        let mut r = XorShift64Star(0x9E37_79B9_7F4A_7C15);
        let n = 20_000;
        let v: Vec<f64> = (0..n).map(|_| r.normal()).collect();
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(
            mean.abs() < 0.05 && (var - 1.0).abs() < 0.05,
            "{mean} {var}"
        );
        assert!((0..1000).map(|_| r.uniform()).all(|u| u > 0.0 && u < 1.0));
    }
}
