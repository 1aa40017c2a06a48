//! Pixel reconstruction filters, as Mitsuba 3 defines them
//! (`src/rfilters/*.cpp`), and the table lancer samples them with.
//!
//! Mitsuba splats every sample into each pixel within the filter's radius,
//! weighted by `f(dx) f(dy)`, and divides each pixel by its sum of weights.
//! lancer importance-samples the filter instead (filter importance
//! sampling, as pbrt-v4 does): a path's film position is the pixel's
//! centre plus an offset drawn from `|f|`, the path counts in its own pixel
//! only, and its throughput starts at `f(x) / (p(x) ∫f)` per axis. In
//! expectation both give `∫ f(x) L(x) dx / ∫ f` per pixel; the film stays a
//! plain sum of samples.
//!
//! The offset is drawn through a tabulated inverse CDF of `|f|` on
//! `[-radius, radius]` ([`FilterTable`]), built once in f64: `u` in [0, 1)
//! falls in segment `j = floor(u M)` of `M` = [`FILTER_TABLE_SEGMENTS`]
//! equal steps of `u`, and `x` moves linearly from `x[j]` to `x[j + 1]`
//! inside it, so its density there is `1 / (M (x[j + 1] - x[j]))`. The
//! weight uses that density exactly, so the table's approximation of `|f|`
//! costs a little variance and no bias. The map is monotone in `u`, so
//! stratified and low-discrepancy `u` stay stratified in `x`.

use super::types::PixelFilter;
use crate::interface::{FILTER_EDGE_ENTRIES, FILTER_TABLE_SEGMENTS};

/// Quadrature steps over `[-radius, radius]` for the filter's integrals.
const QUADRATURE_STEPS: usize = 1 << 16;

/// The tabulated inverse CDF of a filter's `|f|` (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct FilterTable {
    /// `FILTER_TABLE_SEGMENTS + 1` offsets in pixels, from `-radius` to
    /// `radius`, non-decreasing: `x[j]` is where the CDF of `|f|` reaches
    /// `j / FILTER_TABLE_SEGMENTS`.
    pub x: Vec<f64>,
    /// `1 / ∫ f` over `[-radius, radius]`.
    pub inv_integral: f64,
}

impl FilterTable {
    /// The offset `u` in [0, 1) maps to, and its weight `f(x) / (p(x) ∫ f)`
    /// (the device's `sample_filter`, in f64).
    pub fn sample(&self, filter: &PixelFilter, u: f64) -> (f64, f64) {
        let m = FILTER_TABLE_SEGMENTS as usize;
        let s = u * m as f64;
        let j = (s as usize).min(m - 1);
        let t = s - j as f64;
        let (x0, x1) = (self.x[j], self.x[j + 1]);
        let width = x1 - x0;
        let x = x0 + t * width;
        (x, filter.eval(x) * (m as f64 * width) * self.inv_integral)
    }

    /// The table's CDF at offset `x`: the `u` that [`FilterTable::sample`]
    /// maps to `x` (0 below the support, 1 above it).
    pub fn cdf(&self, x: f64) -> f64 {
        let m = self.x.len() - 1;
        if x <= self.x[0] {
            return 0.0;
        }
        if x >= self.x[m] {
            return 1.0;
        }
        let j = (self.x.partition_point(|&v| v <= x) - 1).min(m - 1);
        let width = self.x[j + 1] - self.x[j];
        let t = if width > 0.0 {
            (x - self.x[j]) / width
        } else {
            0.0
        };
        (j as f64 + t) / m as f64
    }

    /// An offset drawn from the filter cut to `[a, b]` and its weight
    /// `f(x) / (p(x) ∫_a^b f)`, with `edge` = (CDF(a), ∫_-r^a f, CDF(b),
    /// ∫_-r^b f), an entry of [`PixelFilter::edge_table`] (the device's
    /// `sample_filter_cut`, in f64): `u` is mapped to `CDF(a) + u (CDF(b) -
    /// CDF(a))` and through the table, so the density is the table's divided
    /// by `CDF(b) - CDF(a)`.
    pub fn sample_cut(&self, filter: &PixelFilter, u: f64, edge: [f64; 4]) -> (f64, f64) {
        let mass = edge[2] - edge[0];
        let (x, w) = self.sample(filter, edge[0] + u * mass);
        (x, w / self.inv_integral * mass / (edge[3] - edge[1]))
    }
}

impl PixelFilter {
    /// The name Mitsuba's `<rfilter type>` and lancer's `render.filter` use.
    pub fn name(&self) -> &'static str {
        match self {
            PixelFilter::Box => "box",
            PixelFilter::Tent { .. } => "tent",
            PixelFilter::Gaussian { .. } => "gaussian",
            PixelFilter::Mitchell { .. } => "mitchell",
            PixelFilter::Lanczos { .. } => "lanczos",
        }
    }

    /// Mitsuba's default filter: a Gaussian of standard deviation 0.5.
    pub const MITSUBA_DEFAULT: PixelFilter = PixelFilter::Gaussian { stddev: 0.5 };

    /// Mitsuba's `catmullrom`: the Mitchell-Netravali cubic with B = 0, C = 0.5.
    pub const CATMULL_ROM: PixelFilter = PixelFilter::Mitchell { b: 0.0, c: 0.5 };

    /// Mitsuba's `mitchell` with its default B = C = 1/3.
    pub const MITCHELL: PixelFilter = PixelFilter::Mitchell {
        b: 1.0 / 3.0,
        c: 1.0 / 3.0,
    };

    /// The filter's support `[-radius, radius]`, in pixels.
    pub fn radius(&self) -> f64 {
        match *self {
            PixelFilter::Box => 0.5,
            PixelFilter::Tent { radius } => radius as f64,
            PixelFilter::Gaussian { stddev } => 4.0 * stddev as f64,
            PixelFilter::Mitchell { .. } => 2.0,
            PixelFilter::Lanczos { lobes } => lobes as f64,
        }
    }

    /// Checks the parameters: what is wrong, naming Mitsuba's property.
    pub fn validate(&self) -> Result<(), String> {
        let bad = |key: &str, x: f32, want: &str| Err(format!("{key} must be {want}, got {x}"));
        match *self {
            PixelFilter::Box => Ok(()),
            PixelFilter::Tent { radius } if !(radius > 0.0 && radius <= 16.0) => {
                bad("radius", radius, "> 0 and at most 16 pixels")
            }
            PixelFilter::Gaussian { stddev } if !(stddev > 0.0 && stddev <= 4.0) => {
                bad("stddev", stddev, "> 0 and at most 4 pixels")
            }
            PixelFilter::Mitchell { b, .. } if !b.is_finite() => bad("B", b, "finite"),
            PixelFilter::Mitchell { c, .. } if !c.is_finite() => bad("C", c, "finite"),
            PixelFilter::Lanczos { lobes } if !(1..=16).contains(&lobes) => Err(format!(
                "lobes must be an integer from 1 to 16, got {lobes}"
            )),
            _ => {
                let integral = self.integrals().0;
                if integral.is_finite() && integral > 1e-6 {
                    Ok(())
                } else {
                    Err(format!(
                        "the filter integrates to {integral:e}; its weights must have a \
                         positive sum"
                    ))
                }
            }
        }
    }

    /// The filter's value at offset `x` pixels from the pixel's centre, as
    /// Mitsuba defines it (its Gaussian is exact here, where Mitsuba's CPU
    /// variants use a polynomial fit of `exp` good to about 1e-7).
    pub fn eval(&self, x: f64) -> f64 {
        match *self {
            PixelFilter::Box => {
                if (-0.5..0.5).contains(&x) {
                    1.0
                } else {
                    0.0
                }
            }
            PixelFilter::Tent { radius } => (1.0 - (x / radius as f64).abs()).max(0.0),
            PixelFilter::Gaussian { stddev } => {
                let alpha = -1.0 / (2.0 * (stddev as f64).powi(2));
                let r = self.radius();
                ((alpha * x * x).exp() - (alpha * r * r).exp()).max(0.0)
            }
            PixelFilter::Mitchell { b, c } => {
                let (b, c) = (b as f64, c as f64);
                let x = x.abs();
                let (x2, x3) = (x * x, x * x * x);
                let v = if x < 1.0 {
                    (12.0 - 9.0 * b - 6.0 * c) * x3
                        + (-18.0 + 12.0 * b + 6.0 * c) * x2
                        + (6.0 - 2.0 * b)
                } else if x < 2.0 {
                    (-b - 6.0 * c) * x3
                        + (6.0 * b + 30.0 * c) * x2
                        + (-12.0 * b - 48.0 * c) * x
                        + (8.0 * b + 24.0 * c)
                } else {
                    0.0
                };
                v / 6.0
            }
            PixelFilter::Lanczos { lobes } => {
                let (x, r) = (x.abs(), lobes as f64);
                if x < f64::from(f32::EPSILON) * 0.5 {
                    1.0
                } else if x > r {
                    0.0
                } else {
                    let x1 = std::f64::consts::PI * x;
                    let x2 = x1 / r;
                    x1.sin() * x2.sin() / (x1 * x2)
                }
            }
        }
    }

    /// `(∫ f, ∫ |f|)` over the support, by the midpoint rule.
    pub fn integrals(&self) -> (f64, f64) {
        let r = self.radius();
        let h = 2.0 * r / QUADRATURE_STEPS as f64;
        let (mut sum, mut abs) = (0.0, 0.0);
        for i in 0..QUADRATURE_STEPS {
            let f = self.eval(-r + (i as f64 + 0.5) * h);
            sum += f * h;
            abs += f.abs() * h;
        }
        (sum, abs)
    }

    /// `∫ f` from `-radius` to `x`, by the midpoint rule at the step of
    /// [`PixelFilter::integrals`].
    pub fn integral_to(&self, x: f64) -> f64 {
        let r = self.radius();
        let x = x.clamp(-r, r);
        let steps = ((QUADRATURE_STEPS as f64 * (x + r) / (2.0 * r)).ceil() as usize).max(1);
        let h = (x + r) / steps as f64;
        (0..steps)
            .map(|i| self.eval(-r + (i as f64 + 0.5) * h) * h)
            .sum()
    }

    /// What the device needs to sample the filter cut at the image's edge
    /// (`Frame.filter_edge`, Mitsuba's `sample_border` false). Entry `k` of
    /// the first 16 is for a pixel `k` whole pixels from the edge, whose
    /// centre is `k + 1/2` from it. Where the filter reaches past the edge
    /// (`k + 1/2` below the radius) it holds `CDF(-d)`, `∫ f` from `-r` to
    /// `-d`, `CDF(d)` and `∫ f` from `-r` to `d`, with `d = k + 1/2`: the
    /// cut below for the left or top edge, above for the right or bottom
    /// one. Other entries, and the last, hold the uncut ends `(0, 0, 1, ∫ f)`.
    pub fn edge_table(&self, table: &FilterTable) -> Vec<[f64; 4]> {
        let r = self.radius();
        let whole = [0.0, 0.0, 1.0, self.integrals().0];
        (0..FILTER_EDGE_ENTRIES as usize)
            .map(|k| {
                let d = k as f64 + 0.5;
                if k + 1 < FILTER_EDGE_ENTRIES as usize && d < r {
                    [
                        table.cdf(-d),
                        self.integral_to(-d),
                        table.cdf(d),
                        self.integral_to(d),
                    ]
                } else {
                    whole
                }
            })
            .collect()
    }

    /// The tabulated inverse CDF of `|f|` the device samples offsets with.
    pub fn table(&self) -> FilterTable {
        let r = self.radius();
        let n = QUADRATURE_STEPS;
        let h = 2.0 * r / n as f64;
        // Cumulative |f| at the quadrature's step ends, by the midpoint rule
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0);
        let mut integral = 0.0;
        for i in 0..n {
            let f = self.eval(-r + (i as f64 + 0.5) * h);
            integral += f * h;
            cdf.push(cdf[i] + f.abs() * h);
        }
        let total = cdf[n];
        let m = FILTER_TABLE_SEGMENTS as usize;
        let mut x = Vec::with_capacity(m + 1);
        x.push(-r);
        let mut i = 0;
        for j in 1..m {
            let target = total * j as f64 / m as f64;
            while i + 1 < n && cdf[i + 1] < target {
                i += 1;
            }
            let step = cdf[i + 1] - cdf[i];
            let t = if step > 0.0 {
                ((target - cdf[i]) / step).clamp(0.0, 1.0)
            } else {
                0.0
            };
            x.push(-r + (i as f64 + t) * h);
        }
        x.push(r);
        FilterTable {
            x,
            inv_integral: 1.0 / integral,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn filters() -> Vec<PixelFilter> {
        vec![
            PixelFilter::Box,
            PixelFilter::Tent { radius: 1.0 },
            PixelFilter::Tent { radius: 1.7 },
            PixelFilter::MITSUBA_DEFAULT,
            PixelFilter::Gaussian { stddev: 0.25 },
            PixelFilter::MITCHELL,
            PixelFilter::CATMULL_ROM,
            PixelFilter::Lanczos { lobes: 3 },
            PixelFilter::Lanczos { lobes: 2 },
        ]
    }

    /// Mitsuba's filters at points worked out by hand.
    #[test]
    fn values_match_mitsubas_definitions() {
        // B and C are f32, as Mitsuba's
        let close = |a: f64, b: f64| assert!((a - b).abs() < 1e-7, "{a} vs {b}");
        close(PixelFilter::Tent { radius: 2.0 }.eval(0.5), 0.75);
        let g = PixelFilter::MITSUBA_DEFAULT;
        close(g.eval(0.5), (-0.5f64).exp() - (-8.0f64).exp());
        close(g.eval(2.0), 0.0);
        // Mitchell (B = C = 1/3): 16/18 at 0, 1/18 at 1, 0 at 2
        let m = PixelFilter::MITCHELL;
        close(m.eval(0.0), 16.0 / 18.0);
        close(m.eval(1.0), 1.0 / 18.0);
        close(m.eval(-2.0), 0.0);
        // Catmull-Rom interpolates: 1 at 0, 0 at 1, -0.0625 at 1.5
        let c = PixelFilter::CATMULL_ROM;
        close(c.eval(0.0), 1.0);
        close(c.eval(1.0), 0.0);
        close(c.eval(1.5), -0.0625);
        let l = PixelFilter::Lanczos { lobes: 3 };
        close(l.eval(0.0), 1.0);
        close(l.eval(1.0), 0.0);
        close(l.eval(3.5), 0.0);
        close(
            l.eval(0.5),
            (0.5 * std::f64::consts::PI).sin() * (std::f64::consts::PI / 6.0).sin()
                / (0.5 * std::f64::consts::PI * std::f64::consts::PI / 6.0),
        );
        assert_eq!(PixelFilter::Box.eval(0.5), 0.0);
        assert_eq!(PixelFilter::Box.eval(-0.5), 1.0);
    }

    /// Sampling cut to `[a, b]` (an edge entry): the weight's mean over `u`
    /// is 1 and the weighted mean of a test function is `∫_a^b f g / ∫_a^b
    /// f`, negative lobes included; offsets stay inside `[a, b]`.
    #[test]
    fn cut_sampling_gives_the_cut_filters_mean() {
        for f in filters() {
            let table = f.table();
            let edges = f.edge_table(&table);
            let r = f.radius();
            assert_eq!(edges.len(), FILTER_EDGE_ENTRIES as usize);
            assert_eq!(edges[16], [0.0, 0.0, 1.0, f.integrals().0]);
            let g = |x: f64| 1.0 + 0.5 * (1.3 * x).sin() + 0.1 * x * x;
            // A pixel 0 or 1 from one edge, and one near both edges of a
            // film 2 pixels wide.
            let cases = [
                ([edges[0][0], edges[0][1], 1.0, edges[16][3]], -0.5, r),
                ([0.0, 0.0, edges[1][2], edges[1][3]], -r, 1.5),
                (
                    [edges[0][0], edges[0][1], edges[1][2], edges[1][3]],
                    -0.5,
                    1.5,
                ),
            ];
            for (edge, a, b) in cases {
                let (a, b) = (a.max(-r), b.min(r));
                let n = 1 << 20;
                let (mut w_sum, mut wg_sum) = (0.0, 0.0);
                for i in 0..n {
                    let u = (i as f64 + 0.5) / n as f64;
                    let (x, w) = table.sample_cut(&f, u, edge);
                    assert!(
                        x >= a - 1e-9 && x <= b + 1e-9,
                        "{f:?}: {x} outside [{a}, {b}]"
                    );
                    w_sum += w;
                    wg_sum += w * g(x);
                }
                let steps = 1 << 16;
                let h = (b - a) / steps as f64;
                let (mut fg, mut ff) = (0.0, 0.0);
                for i in 0..steps {
                    let x = a + (i as f64 + 0.5) * h;
                    fg += f.eval(x) * g(x) * h;
                    ff += f.eval(x) * h;
                }
                let mean_w = w_sum / n as f64;
                let mean_wg = wg_sum / n as f64;
                assert!(
                    (mean_w - 1.0).abs() < 2e-4,
                    "{f:?} [{a}, {b}]: mean weight {mean_w}"
                );
                assert!(
                    (mean_wg - fg / ff).abs() < 2e-4 * (fg / ff).abs().max(1.0),
                    "{f:?} [{a}, {b}]: {mean_wg} vs {}",
                    fg / ff
                );
            }
        }
    }

    /// The Mitchell-Netravali family integrates to 1 for every B and C.
    #[test]
    fn mitchell_integrates_to_one() {
        for f in [PixelFilter::MITCHELL, PixelFilter::CATMULL_ROM] {
            let (sum, abs) = f.integrals();
            assert!((sum - 1.0).abs() < 1e-9, "{f:?}: {sum}");
            assert!(abs > 1.0, "{f:?} has negative lobes: {abs}");
        }
    }

    /// The density the weights assume: `1 / (M width)` on each table segment.
    fn table_density_mass(table: &FilterTable, a: f64, z: f64) -> f64 {
        let m = FILTER_TABLE_SEGMENTS as f64;
        table
            .x
            .windows(2)
            .map(|w| {
                let overlap = (z.min(w[1]) - a.max(w[0])).max(0.0);
                overlap / (m * (w[1] - w[0]))
            })
            .sum()
    }

    /// Offsets drawn through the table fall into 40 bins over the support
    /// as the density in the weights predicts (χ² test at 1e-3
    /// significance): the weight's pdf is the sampler's pdf.
    #[test]
    fn sampled_offsets_follow_the_weights_density_chi2() {
        const BINS: usize = 40;
        const N: usize = 200_000;
        for f in filters() {
            let table = f.table();
            let r = f.radius();
            let mut counts = [0usize; BINS];
            // A 64-bit LCG's top bits: reproducible and independent enough
            let mut state = 0x9E37_79B9_7F4A_7C15u64;
            for _ in 0..N {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let u = (state >> 11) as f64 / (1u64 << 53) as f64;
                let (x, _) = table.sample(&f, u);
                assert!(x >= -r && x <= r, "{f:?}: {x} outside the support");
                let bin = (((x + r) / (2.0 * r)) * BINS as f64) as usize;
                counts[bin.min(BINS - 1)] += 1;
            }
            let mut chi2 = 0.0;
            let mut dof = 0;
            for (b, &count) in counts.iter().enumerate() {
                let a = -r + 2.0 * r * b as f64 / BINS as f64;
                let z = -r + 2.0 * r * (b + 1) as f64 / BINS as f64;
                let expected = table_density_mass(&table, a, z) * N as f64;
                assert!(expected >= 5.0, "{f:?} bin {b}: expected {expected}");
                chi2 += (count as f64 - expected).powi(2) / expected;
                dof += 1;
            }
            // χ² critical value at 1e-3 for dof - 1 degrees of freedom (Wilson-Hilferty)
            let k = (dof - 1) as f64;
            let z = 3.09;
            let critical = k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3);
            assert!(
                chi2 < critical,
                "{f:?}: χ² {chi2:.1} over {dof} bins, critical {critical:.1}"
            );
        }
    }

    /// The table's density is close to |f| / ∫|f|: the weights stay near
    /// their ideal constant (total variation distance below 2%, so the
    /// offsets' histogram matches the filter's).
    #[test]
    fn table_density_matches_the_filter() {
        for f in filters() {
            let table = f.table();
            let (_, total) = f.integrals();
            let r = f.radius();
            let bins = 400;
            let mut distance = 0.0;
            for b in 0..bins {
                let a = -r + 2.0 * r * b as f64 / bins as f64;
                let z = -r + 2.0 * r * (b + 1) as f64 / bins as f64;
                let steps = 200;
                let h = (z - a) / steps as f64;
                let exact: f64 = (0..steps)
                    .map(|i| f.eval(a + (i as f64 + 0.5) * h).abs() * h)
                    .sum::<f64>()
                    / total;
                distance += 0.5 * (table_density_mass(&table, a, z) - exact).abs();
            }
            assert!(distance < 0.02, "{f:?}: total variation {distance}");
        }
    }

    /// The weighted offsets integrate exactly: over u in [0, 1) (fine
    /// midpoint rule), the mean weight is 1 and the weighted second moment
    /// is the filter's own ∫ x² f / ∫ f; the table's error leaves no bias.
    #[test]
    fn weighted_offsets_reproduce_the_filters_moments() {
        for f in filters() {
            let table = f.table();
            let n = 1 << 20;
            let (mut w0, mut w2) = (0.0, 0.0);
            for i in 0..n {
                let u = (i as f64 + 0.5) / n as f64;
                let (x, w) = table.sample(&f, u);
                w0 += w / n as f64;
                w2 += w * x * x / n as f64;
            }
            let r = f.radius();
            let steps = 1 << 20;
            let h = 2.0 * r / steps as f64;
            let (mut m0, mut m2) = (0.0, 0.0);
            for i in 0..steps {
                let x = -r + (i as f64 + 0.5) * h;
                m0 += f.eval(x) * h;
                m2 += x * x * f.eval(x) * h;
            }
            let second = m2 / m0;
            assert!((w0 - 1.0).abs() < 1e-4, "{f:?}: mean weight {w0}");
            assert!(
                (w2 - second).abs() < 1e-4 * second.abs().max(1e-2),
                "{f:?}: {w2} vs {second}"
            );
        }
    }

    /// Tables start and end at the support's ends and never go back.
    #[test]
    fn tables_are_monotone() {
        for f in filters() {
            let t = f.table();
            assert_eq!(t.x.len(), FILTER_TABLE_SEGMENTS as usize + 1);
            assert_eq!(t.x[0], -f.radius());
            assert_eq!(*t.x.last().unwrap(), f.radius());
            assert!(t.x.windows(2).all(|w| w[0] < w[1]), "{f:?}");
        }
    }

    #[test]
    fn bad_parameters_are_refused_by_name() {
        let e = PixelFilter::Gaussian { stddev: 0.0 }
            .validate()
            .unwrap_err();
        assert!(e.starts_with("stddev"), "{e}");
        let e = PixelFilter::Tent { radius: -1.0 }.validate().unwrap_err();
        assert!(e.starts_with("radius"), "{e}");
        let e = PixelFilter::Lanczos { lobes: 0 }.validate().unwrap_err();
        assert!(e.starts_with("lobes"), "{e}");
        // B = 0, C = -1 is fine; a filter that sums to nothing is not
        assert!(PixelFilter::Mitchell { b: 0.0, c: -1.0 }.validate().is_ok());
        assert!(PixelFilter::Mitchell {
            b: f32::NAN,
            c: 0.0
        }
        .validate()
        .is_err());
    }
}
