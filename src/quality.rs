//! Signal quality against a known truth: SNR, MSE, RMS.

/// SNR in dB: `10 log10(sum s^2 / sum (s - s_hat)^2)`; infinite for a perfect estimate.
pub fn snr_db(truth: &[f64], estimate: &[f64]) -> f64 {
    let signal: f64 = truth.iter().map(|s| s * s).sum();
    let error: f64 = truth
        .iter()
        .zip(estimate)
        .map(|(s, e)| (s - e) * (s - e))
        .sum();
    10.0 * (signal / error).log10()
}

/// Mean squared error between `truth` and `estimate`.
pub fn mse(truth: &[f64], estimate: &[f64]) -> f64 {
    let n = truth.len().min(estimate.len()).max(1);
    truth
        .iter()
        .zip(estimate)
        .map(|(s, e)| (s - e) * (s - e))
        .sum::<f64>()
        / n as f64
}

/// Root mean square of `x - y`: what a denoiser removed when `x` is its input and `y` its output.
pub fn rms_diff(x: &[f64], y: &[f64]) -> f64 {
    mse(x, y).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snr_and_mse_by_hand() {
        let s = [1.0, -1.0, 1.0, -1.0];
        let e = [1.1, -0.9, 0.9, -1.1];
        assert!((mse(&s, &e) - 0.01).abs() < 1e-15);
        assert!((snr_db(&s, &e) - 20.0).abs() < 1e-12);
        assert!((rms_diff(&s, &e) - 0.1).abs() < 1e-15);
        assert_eq!(snr_db(&s, &s), f64::INFINITY);
    }
}
