//! Measurements on probe time series: vibration frequency by a least-squares sinusoid fit, peak
//! deflection.

/// Frequency (Hz) of the dominant oscillation of `u(t)`: the frequency f that minimises the
/// residual of the least-squares fit u ~ a + b cos(2 pi f t) + c sin(2 pi f t), searched on a
/// grid in [f_lo, f_hi] and refined by golden section. Robust to an unknown mean (the static
/// deflection) and to small higher-mode content. None when fewer than 8 samples.
pub fn dominant_frequency(t: &[f64], u: &[f64], f_lo: f64, f_hi: f64) -> Option<f64> {
    if t.len() < 8 || t.len() != u.len() || !(f_hi > f_lo && f_lo > 0.0) {
        return None;
    }
    let grid = 800;
    let mut best = (f64::INFINITY, f_lo);
    for k in 0..=grid {
        let f = f_lo * (f_hi / f_lo).powf(k as f64 / grid as f64);
        let r = fit_residual(t, u, f);
        if r < best.0 {
            best = (r, f);
        }
    }
    let step = (f_hi / f_lo).powf(1.0 / grid as f64);
    let (mut a, mut b) = (best.1 / step, best.1 * step);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..60 {
        let c = b - g * (b - a);
        let d = a + g * (b - a);
        if fit_residual(t, u, c) < fit_residual(t, u, d) {
            b = d;
        } else {
            a = c;
        }
    }
    Some(0.5 * (a + b))
}

/// Residual sum of squares of the 3-parameter fit at frequency f.
fn fit_residual(t: &[f64], u: &[f64], f: f64) -> f64 {
    let w = 2.0 * std::f64::consts::PI * f;
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atb = nalgebra::Vector3::<f64>::zeros();
    for (&ti, &ui) in t.iter().zip(u) {
        let row = nalgebra::Vector3::new(1.0, (w * ti).cos(), (w * ti).sin());
        ata += row * row.transpose();
        atb += row * ui;
    }
    let Some(x) = ata.try_inverse().map(|inv| inv * atb) else {
        return f64::INFINITY;
    };
    t.iter()
        .zip(u)
        .map(|(&ti, &ui)| {
            let e = ui - (x[0] + x[1] * (w * ti).cos() + x[2] * (w * ti).sin());
            e * e
        })
        .sum()
}

/// The sample of largest magnitude (signed).
pub fn peak(u: &[f64]) -> f64 {
    u.iter()
        .copied()
        .fold(0.0, |a: f64, v| if v.abs() > a.abs() { v } else { a })
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn recovers_frequency_of_step_response_with_second_mode() {
        // u = -1 + cos(2 pi 10.7 t) + 0.05 sin(2 pi 37 t): the fit must find 10.7 Hz within
        // 0.1 % (the grid is refined to machine precision; the second mode biases slightly).
        let t: Vec<f64> = (0..600).map(|k| k as f64 * 1e-3).collect();
        let u: Vec<f64> = t
            .iter()
            .map(|&t| {
                -1.0 + (2.0 * std::f64::consts::PI * 10.7 * t).cos()
                    + 0.05 * (2.0 * std::f64::consts::PI * 37.0 * t).sin()
            })
            .collect();
        let f = dominant_frequency(&t, &u, 2.0, 40.0).unwrap();
        assert!((f - 10.7).abs() < 0.0107, "{f}");
        assert_eq!(peak(&[0.5, -2.0, 1.0]), -2.0);
    }
}
