//! Per-value error metrics of an image against a reference, and the error
//! a film's own variance predicts: pure functions of two slices, used by
//! budgets while rendering and by every analysis.

/// Number of values that are NaN or infinite.
pub fn count_nonfinite(xs: &[f32]) -> usize {
    xs.iter().filter(|x| !x.is_finite()).count()
}

/// Mean over paired values of `f(a, b)`, in f64; 0 for empty slices.
fn mean_of(a: &[f32], b: &[f32], f: impl Fn(f64, f64) -> f64) -> f64 {
    assert_eq!(a.len(), b.len(), "images differ in length");
    if a.is_empty() {
        return 0.0;
    }
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| f(f64::from(x), f64::from(y)))
        .sum();
    sum / a.len() as f64
}

/// Root mean squared error of `a` against `b`, over every value: sqrt(mean((a-b)²)).
///
/// Non-finite inputs give a non-finite result (check with
/// [`count_nonfinite`]); empty slices give 0.
///
/// # Panics
///
/// If the slices differ in length.
pub fn rmse(a: &[f32], b: &[f32]) -> f64 {
    mean_of(a, b, |x, y| (x - y) * (x - y)).sqrt()
}

/// Relative mean squared error of `a` against the reference `b`:
/// mean((a-b)² / (b² + 0.01)).
///
/// Non-finite inputs give a non-finite result; empty slices give 0.
///
/// # Panics
///
/// If the slices differ in length.
pub fn rel_mse(a: &[f32], b: &[f32]) -> f64 {
    mean_of(a, b, |x, y| (x - y) * (x - y) / (y * y + 0.01))
}

/// Mean bias of `a` against the reference `b`: mean(a - b).
///
/// Non-finite inputs give a non-finite result; empty slices give 0.
///
/// # Panics
///
/// If the slices differ in length.
pub fn mean_bias(a: &[f32], b: &[f32]) -> f64 {
    mean_of(a, b, |x, y| x - y)
}

/// Largest difference between paired values: max |a - b|, in f64.
///
/// A NaN difference (a NaN input, or infinities of the same sign) makes the
/// result NaN; an infinite difference makes it infinite; empty slices give 0.
///
/// # Panics
///
/// If the slices differ in length.
pub fn max_abs_diff(a: &[f32], b: &[f32]) -> f64 {
    assert_eq!(a.len(), b.len(), "images differ in length");
    let mut max = 0.0f64;
    for (&x, &y) in a.iter().zip(b) {
        let d = (f64::from(x) - f64::from(y)).abs();
        if d.is_nan() {
            return f64::NAN;
        }
        max = max.max(d);
    }
    max
}

/// The relMSE that a film's own variance (or error estimate) predicts:
/// `mean(var_of_mean / (reference² + 0.01))` over every value.
///
/// For an unbiased image whose values have variance of the mean
/// `var_of_mean` (renders pass their two half films' error estimate,
/// `RenderOutput::error_estimate`, which holds under every sampler), this is the expected value of [`rel_mse`] against an exact
/// `reference`: `E[(a-b)²] = Var(a)` when `E[a] = b`. A measured relMSE well
/// above it means bias (or a noisy reference: the reference's own variance
/// adds to the measured figure but not to this one). Negative variances
/// (round-off in a sum of squares) count as 0; non-finite inputs give a
/// non-finite result; empty slices give 0.
///
/// # Panics
///
/// If the slices differ in length.
pub fn predicted_rel_mse(var_of_mean: &[f32], reference: &[f32]) -> f64 {
    mean_of(var_of_mean, reference, |v, r| {
        let v = if v < 0.0 { 0.0 } else { v };
        v / (r * r + 0.01)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_figures() {
        let a = [1.0f32, 2.0, 3.0, 4.0];
        let b = [1.0f32, 1.0, 3.0, 2.0];
        assert!((rmse(&a, &b) - (5.0f64 / 4.0).sqrt()).abs() < 1e-12);
        let want = (1.0 / 1.01 + 4.0 / 4.01) / 4.0;
        assert!((rel_mse(&a, &b) - want).abs() < 1e-12);
        assert!((mean_bias(&a, &b) - 0.75).abs() < 1e-12);
        assert_eq!(rmse(&[], &[]), 0.0);
        assert_eq!(
            count_nonfinite(&[1.0, f32::NAN, f32::INFINITY, -0.0, f32::NEG_INFINITY]),
            3
        );
        assert!(rmse(&[f32::NAN], &[0.0]).is_nan());
    }
}
