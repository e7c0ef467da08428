//! A 2nd-order Bessel low-pass filter in discrete time, for smoothing trajectories.
//!
//! The analog prototype is H(s) = 3 / (s² + 3s + 3) (unit group delay at DC; a damping ratio
//! of √3/2). Its −3 dB frequency is ω_p = √((√45 − 3) / 2) ≈ 1.3617 rad/s, so it is scaled by
//! ω_c / ω_p to put the −3 dB point at the cutoff ω_c = 2π·f_c. It is made discrete with the
//! bilinear transform s = (2/T)·(z − 1)/(z + 1), the cutoff prewarped (ω_c → (2/T)·tan(ω_c·T/2))
//! so that the discrete filter is −3 dB at exactly f_c. With u = ω_p / tan(π·f_c·T):
//!
//! ```text
//!          3 + 6 z⁻¹ + 3 z⁻²
//! H(z) = ---------------------------------------------------
//!        (u² + 3u + 3) + (6 − 2u²) z⁻¹ + (u² − 3u + 3) z⁻²
//! ```
//!
//! Its DC gain is exactly 1 (both sides sum to 12). Its step response is nearly that of a
//! critically damped system: it rises monotonically, never undershoots, and settles without
//! ringing, but a 2nd-order Bessel does overshoot a step, by 0.43 % (e^(−π·ζ/√(1 − ζ²)) with
//! ζ = √3/2). The bilinear transform keeps that while the cutoff is well below the sample rate
//! (0.44 % at f_c·T = 0.02, 0.49 % at 0.05) and warps it nearer Nyquist (0.7 % at 0.1, 1.6 %
//! at 0.16). Since the step response is never negative, a monotone input from a to b never
//! leaves [a, b] by more than that fraction of |b − a|; the smooth inputs of a trajectory
//! (bounded acceleration) overshoot far less.

/// Why a filter cannot be made: its sample period or its cutoff.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum FilterError {
    #[error("the sample period must be positive, not {period_s} s")]
    Period { period_s: f64 },
    #[error(
        "the cutoff must be above 0 and below the Nyquist frequency {nyquist_hz} Hz, not \
         {cutoff_hz} Hz"
    )]
    Cutoff { cutoff_hz: f64, nyquist_hz: f64 },
}

/// One 2nd-order section, direct form II transposed. `Copy`: no allocation anywhere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bessel2 {
    /// Numerator b0, b1, b2, normalised by a0.
    b: [f64; 3],
    /// Denominator a1, a2, normalised by a0.
    a: [f64; 2],
    /// The two state variables of the transposed direct form.
    s: [f64; 2],
}

impl Bessel2 {
    /// Carries the filter's state (its coefficients come from its parameters).
    pub fn carry(
        &mut self,
        c: &mut modbot_grid::carry::Carry<'_>,
    ) -> Result<(), modbot_grid::carry::CarryError> {
        c.f64s("a filter's state", &mut self.s)
    }

    /// A filter with its −3 dB point at `cutoff_hz`, sampled every `period_s` seconds, at
    /// rest at 0. The cutoff must be positive and below the Nyquist frequency 1 / (2·period_s).
    pub fn new(cutoff_hz: f64, period_s: f64) -> Result<Bessel2, FilterError> {
        if !(period_s.is_finite() && period_s > 0.0) {
            return Err(FilterError::Period { period_s });
        }
        let nyquist_hz = 0.5 / period_s;
        if !(cutoff_hz.is_finite() && cutoff_hz > 0.0 && cutoff_hz < nyquist_hz) {
            return Err(FilterError::Cutoff {
                cutoff_hz,
                nyquist_hz,
            });
        }
        let prototype_cutoff = ((45f64.sqrt() - 3.0) / 2.0).sqrt();
        let u = prototype_cutoff / (std::f64::consts::PI * cutoff_hz * period_s).tan();
        let a0 = u * u + 3.0 * u + 3.0;
        Ok(Bessel2 {
            b: [3.0 / a0, 6.0 / a0, 3.0 / a0],
            a: [(6.0 - 2.0 * u * u) / a0, (u * u - 3.0 * u + 3.0) / a0],
            s: [0.0; 2],
        })
    }

    /// Puts the filter at rest at `x`: its output is `x` for as long as its input is.
    pub fn reset(&mut self, x: f64) {
        let [b0, b1, b2] = self.b;
        let [a1, a2] = self.a;
        self.s[1] = (b2 - a2) * x;
        self.s[0] = (b1 - a1) * x + self.s[1];
        // Exactly x out for x in: b0·x + s0 = x up to rounding, as b0 + b1 + b2 = 1 + a1 + a2.
        debug_assert!((b0 * x + self.s[0] - x).abs() <= 1e-12 * x.abs().max(1.0));
    }

    /// Filters one sample.
    pub fn step(&mut self, x: f64) -> f64 {
        let [b0, b1, b2] = self.b;
        let [a1, a2] = self.a;
        let y = b0 * x + self.s[0];
        self.s[0] = b1 * x - a1 * y + self.s[1];
        self.s[1] = b2 * x - a2 * y;
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step_response(cutoff_hz: f64, period_s: f64, samples: usize) -> Vec<f64> {
        let mut sut = Bessel2::new(cutoff_hz, period_s).unwrap();
        (0..samples).map(|_| sut.step(1.0)).collect()
    }

    #[test]
    fn dc_gain_is_one() {
        let y = step_response(10.0, 0.001, 2000);
        assert!((y[1999] - 1.0).abs() < 1e-12, "{}", y[1999]);
        let mut sut = Bessel2::new(3.0, 0.002).unwrap();
        sut.reset(-2.5);
        for _ in 0..100 {
            assert!((sut.step(-2.5) + 2.5).abs() < 1e-12);
        }
    }

    #[test]
    fn step_response_rises_monotonically_to_its_small_bessel_overshoot() {
        for (cutoff_hz, period_s) in [(10.0, 0.001), (2.0, 0.001), (5.0, 0.004)] {
            let y = step_response(cutoff_hz, period_s, 5000);
            let peak = y.iter().cloned().fold(f64::MIN, f64::max);
            let peak_at = y.iter().position(|&v| v == peak).unwrap();
            assert!(
                peak > 1.004 && peak < 1.0045,
                "{cutoff_hz} Hz: overshoot {}",
                peak - 1.0
            );
            assert!(
                y[..peak_at].windows(2).all(|w| w[1] >= w[0]),
                "{cutoff_hz} Hz"
            );
            assert!(y.iter().all(|&v| v >= 0.0), "{cutoff_hz} Hz: undershoot");
        }
    }

    #[test]
    fn cutoff_is_where_the_gain_is_minus_3_db() {
        let (cutoff_hz, period_s) = (10.0, 0.001);
        let mut sut = Bessel2::new(cutoff_hz, period_s).unwrap();
        let w = 2.0 * std::f64::consts::PI * cutoff_hz * period_s;
        let amplitude = (0..20_000)
            .map(|k| sut.step((w * k as f64).sin()))
            .skip(10_000)
            .fold(0.0f64, |m, y| m.max(y.abs()));
        assert!((amplitude - 0.5f64.sqrt()).abs() < 1e-3, "{amplitude}");
    }

    #[test]
    fn a_cutoff_at_or_above_nyquist_is_refused() {
        let sut = Bessel2::new(500.0, 0.001).unwrap_err();
        assert_eq!(
            sut,
            FilterError::Cutoff {
                cutoff_hz: 500.0,
                nyquist_hz: 500.0
            }
        );
        assert_eq!(
            sut.to_string(),
            "the cutoff must be above 0 and below the Nyquist frequency 500 Hz, not 500 Hz"
        );
        assert!(Bessel2::new(0.0, 0.001).is_err());
        assert!(Bessel2::new(f64::NAN, 0.001).is_err());
    }
}
