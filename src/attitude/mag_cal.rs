//! The magnetometer's own calibration from a recorded rotation: hard and soft iron by an
//! ellipsoid fit of the readings, pure maths (what `driftless mag-cal` prints).
//!
//! A reading is `m = W^-1 h_body + b`: the earth's field `h` seen in the body, distorted by the
//! soft iron (a symmetric `W^-1`: steel near the sensor that the field magnetises) and offset
//! by the hard iron `b` (a magnet moving with the sensor). Turned through every direction, the
//! readings lie on an ellipsoid centred on `b`; `W (m - b)` lies on a sphere.
//!
//! - **The fit** ([`fit`]): the algebraic least-squares quadric (ten parameters, the total least
//!   squares solution: the least eigenvector of the design's scatter, on readings centred and
//!   scaled so that the scatter is well conditioned), its centre `b` and shape `M` with
//!   `(m - b)^T M (m - b) = 1`, then `W = r M^(1/2)` with `r = det(M)^(-1/6)`: `det W = 1`,
//!   so `W` keeps the field's magnitude (the sphere's radius is the ellipsoid's geometric
//!   mean radius). Without enough coverage for the ellipsoid the hard iron alone is fitted:
//!   the sphere `|m - b|^2 = r^2`, linear in `b` and `r^2 - |b|^2`.
//! - **The offset's uncertainty** ([`MagCal::hard_iron_sd`]): the Gauss-Newton covariance of
//!   `b` and `r` on the geometric residuals `|W (m - b)| - r`, `W` held (white noise assumed,
//!   so a lower bound).
//! - **Coverage** ([`Coverage`]): the readings' directions from the centre, `u = (m - b) /
//!   |m - b|`. Their centred scatter's least eigenvalue ([`Coverage::spread`]: 0 when every
//!   reading lies in one band, that is the sensor turned about one axis only; 1/3 for the whole
//!   sphere) and the fraction of the sphere's [`CELLS`] equal-area cells holding a reading
//!   ([`Coverage::cells`]). A band cannot fix the offset along the turning axis (a circle lies on
//!   many spheres): refused ([`MagCalError::Band`], naming the axis). Soft iron needs more
//!   ([`SOFT_MIN_SPREAD`], [`SOFT_MIN_CELLS`]: two circles still lie on many ellipsoids); with
//!   less, the hard iron alone ([`Extent::HardIron`], saying why).

use nalgebra::{Matrix3, SMatrix, SymmetricEigen, Vector3};

use super::hard_iron::Mat3;

/// The fewest readings fitted.
pub const MIN_READINGS: usize = 50;
/// The least [`Coverage::spread`] for the hard iron: the directions' spread across the band
/// of a single turning axis (an 8 deg standard deviation off it).
pub const HARD_MIN_SPREAD: f64 = 0.02;
/// The least [`Coverage::spread`] for the soft iron as well.
pub const SOFT_MIN_SPREAD: f64 = 0.05;
/// The least [`Coverage::cells`] for the soft iron as well.
pub const SOFT_MIN_CELLS: f64 = 0.5;
/// The largest condition number of a soft-iron matrix taken (its largest over its least
/// eigenvalue): a sensor's own soft iron is a few percent; this much is a bad fit.
pub const MAX_CONDITION: f64 = 3.0;
/// Equal-area cells of the sphere for [`Coverage::cells`]: 6 bands of equal height (equal area,
/// by Archimedes) times 12 sectors.
pub const CELLS: usize = 72;
const BANDS: usize = 6;
const SECTORS: usize = 12;

/// A calibration: `W (m - b)` is the field in the body, of the readings' magnitude.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// The hard-iron offset `b`, the readings' units.
    pub hard_iron: [f64; 3],
    /// The soft-iron matrix `W`, symmetric, rows first (the identity for the hard iron only).
    pub soft_iron: Mat3,
}

impl Calibration {
    /// No correction.
    pub const IDENTITY: Calibration = Calibration {
        hard_iron: [0.0; 3],
        soft_iron: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    };

    /// A reading corrected: `W (m - b)`.
    pub fn apply(&self, m: &[f64; 3]) -> [f64; 3] {
        let d = [0, 1, 2].map(|i| m[i] - self.hard_iron[i]);
        self.soft_iron
            .map(|row| row[0] * d[0] + row[1] * d[1] + row[2] * d[2])
    }
}

/// Why a soft-iron matrix cannot be used (the caller names its key).
pub fn check_soft_iron(w: &Mat3) -> Result<(), String> {
    if w.iter().flatten().any(|v| !v.is_finite()) {
        return Err("must hold finite numbers".into());
    }
    let m = to_matrix(w);
    if (m - m.transpose()).abs().max() > 1e-6 * m.abs().max() {
        return Err("must be symmetric (what `driftless mag-cal` prints is)".into());
    }
    let e = SymmetricEigen::new(m).eigenvalues;
    let (lo, hi) = (e.min(), e.max());
    if lo <= 0.0 {
        return Err(format!(
            "must be positive definite (its least eigenvalue is {lo:.3})"
        ));
    }
    if hi / lo > MAX_CONDITION {
        return Err(format!(
            "is too stretched for a soft iron (condition {:.2}, at most {MAX_CONDITION})",
            hi / lo
        ));
    }
    Ok(())
}

/// How much of the sphere of directions the readings cover (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coverage {
    /// The least eigenvalue of the directions' centred scatter: 0 for a band, 1/3 for the
    /// whole sphere.
    pub spread: f64,
    /// Its eigenvector, body frame: the axis the sensor turned about when `spread` is small.
    pub axis: [f64; 3],
    /// The fraction of [`CELLS`] equal-area cells of the sphere holding a reading.
    pub cells: f64,
    /// Whether some reading had each body axis +x, -x, +y, -y, +z, -z within 60 deg of the
    /// field's direction.
    pub faces: [bool; 6],
}

/// The directions of the readings about `centre`.
pub fn coverage(readings: &[[f64; 3]], centre: &[f64; 3]) -> Coverage {
    let mut mean = Vector3::zeros();
    let mut scatter = Matrix3::zeros();
    let mut visited = [false; CELLS];
    let mut faces = [false; 6];
    let mut n = 0.0;
    for m in readings {
        let d = Vector3::new(m[0] - centre[0], m[1] - centre[1], m[2] - centre[2]);
        let norm = d.norm();
        if !(norm > 0.0 && norm.is_finite()) {
            continue;
        }
        let u = d / norm;
        n += 1.0;
        mean += u;
        scatter += u * u.transpose();
        let band = (((u.z + 1.0) / 2.0 * BANDS as f64) as usize).min(BANDS - 1);
        let angle = u.y.atan2(u.x) + std::f64::consts::PI;
        let sector = ((angle / std::f64::consts::TAU * SECTORS as f64) as usize).min(SECTORS - 1);
        visited[band * SECTORS + sector] = true;
        for (k, face) in faces.iter_mut().enumerate() {
            let along = u[k / 2] * if k % 2 == 0 { 1.0 } else { -1.0 };
            *face |= along > 0.5;
        }
    }
    if n == 0.0 {
        return Coverage {
            spread: 0.0,
            axis: [0.0, 0.0, 1.0],
            cells: 0.0,
            faces,
        };
    }
    mean /= n;
    let centred = scatter / n - mean * mean.transpose();
    let eigen = SymmetricEigen::new(centred);
    let k = eigen.eigenvalues.imin();
    let axis = eigen.eigenvectors.column(k);
    Coverage {
        spread: eigen.eigenvalues[k].max(0.0),
        axis: [axis[0], axis[1], axis[2]],
        cells: visited.iter().filter(|v| **v).count() as f64 / CELLS as f64,
        faces,
    }
}

impl Coverage {
    /// The turning axis as words: "its z axis", or a direction when no body axis is near.
    pub fn axis_words(&self) -> String {
        let a = self.axis;
        let k = (0..3)
            .max_by(|i, j| a[*i].abs().total_cmp(&a[*j].abs()))
            .unwrap_or(2);
        if a[k].abs() > 25f64.to_radians().cos() {
            format!("its {} axis", ["x", "y", "z"][k])
        } else {
            format!("the body direction ({:.2}, {:.2}, {:.2})", a[0], a[1], a[2])
        }
    }

    /// The body axes never turned towards the field ("+x, -z"), empty when every one was.
    pub fn missing_faces(&self) -> String {
        const NAMES: [&str; 6] = ["+x", "-x", "+y", "-y", "+z", "-z"];
        NAMES
            .iter()
            .zip(self.faces)
            .filter(|(_, seen)| !seen)
            .map(|(n, _)| *n)
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// What was fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Extent {
    /// Hard and soft iron: the ellipsoid.
    Full,
    /// The hard iron alone (the sphere); the soft iron is the identity.
    HardIron,
}

/// A calibration fitted, and how good it is.
#[derive(Debug, Clone, PartialEq)]
pub struct MagCal {
    /// The calibration.
    pub cal: Calibration,
    /// What it corrects.
    pub extent: Extent,
    /// Why the soft iron was not fitted, with [`Extent::HardIron`].
    pub why_hard_only: Option<String>,
    /// Standard deviation of each axis of the hard iron, the readings' units.
    pub hard_iron_sd: [f64; 3],
    /// The field's magnitude: the radius of `W (m - b)`.
    pub field: f64,
    /// RMS of `|m|` about its mean, before: the spread of the field's norm the calibration
    /// removes.
    pub rms_before: f64,
    /// RMS of `|W (m - b)| - field`, after.
    pub rms_after: f64,
    /// The readings' directions about the fitted centre.
    pub coverage: Coverage,
    /// Readings fitted.
    pub readings: usize,
}

/// Why no calibration could be fitted.
#[derive(Debug, Clone, PartialEq)]
pub enum MagCalError {
    /// Fewer usable (finite) readings than [`MIN_READINGS`].
    TooFew(usize),
    /// The readings lie in one band: the sensor turned about one axis only.
    Band(Coverage),
    /// The readings fit no sphere (all equal, or degenerate).
    Degenerate(String),
}

impl std::fmt::Display for MagCalError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MagCalError::TooFew(n) => write!(
                f,
                "{n} usable magnetometer readings: at least {MIN_READINGS} are needed"
            ),
            MagCalError::Band(c) => write!(
                f,
                "the readings cover only a band (spread {:.3}, at least {HARD_MIN_SPREAD} \
                 needed): the sensor turned about {} only; rotate it about the other axes too \
                 (tumble it so that each face points along the field in turn)",
                c.spread,
                c.axis_words()
            ),
            MagCalError::Degenerate(why) => write!(f, "the readings fit no sphere: {why}"),
        }
    }
}

impl std::error::Error for MagCalError {}

fn to_matrix(w: &Mat3) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| w[i][j])
}

fn from_matrix(m: &Matrix3<f64>) -> Mat3 {
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| m[(i, j)]))
}

/// The mean of the readings and their RMS distance from it.
fn centre_scale(readings: &[[f64; 3]]) -> (Vector3<f64>, f64) {
    let n = readings.len() as f64;
    let c = readings
        .iter()
        .fold(Vector3::zeros(), |s, m| s + Vector3::from(*m))
        / n;
    let s = (readings
        .iter()
        .map(|m| (Vector3::from(*m) - c).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    (c, s)
}

/// The sphere's centre (the hard iron alone): `|m - b|^2 = r^2` by linear least squares, on
/// readings centred and scaled.
fn sphere(readings: &[[f64; 3]]) -> Result<[f64; 3], MagCalError> {
    let (c, s) = centre_scale(readings);
    if !(s > 0.0 && s.is_finite()) {
        return Err(MagCalError::Degenerate("every reading is the same".into()));
    }
    // |p|^2 = 2 p . b' + k, p = (m - c) / s.
    let mut ata = SMatrix::<f64, 4, 4>::zeros();
    let mut aty = SMatrix::<f64, 4, 1>::zeros();
    for m in readings {
        let p = (Vector3::from(*m) - c) / s;
        let row = SMatrix::<f64, 4, 1>::new(2.0 * p.x, 2.0 * p.y, 2.0 * p.z, 1.0);
        ata += row * row.transpose();
        aty += row * p.norm_squared();
    }
    let x = ata
        .cholesky()
        .map(|ch| ch.solve(&aty))
        .ok_or_else(|| MagCalError::Degenerate("the sphere's equations are singular".into()))?;
    let b = c + Vector3::new(x[0], x[1], x[2]) * s;
    Ok([b.x, b.y, b.z])
}

/// The ellipsoid: its centre and `W` (see the module documentation), or why not.
fn ellipsoid(readings: &[[f64; 3]]) -> Result<([f64; 3], Mat3), String> {
    let (c, s) = centre_scale(readings);
    let mut scatter = SMatrix::<f64, 10, 10>::zeros();
    for m in readings {
        let p = (Vector3::from(*m) - c) / s;
        let (x, y, z) = (p.x, p.y, p.z);
        let row = SMatrix::<f64, 10, 1>::from_column_slice(&[
            x * x,
            y * y,
            z * z,
            2.0 * x * y,
            2.0 * x * z,
            2.0 * y * z,
            2.0 * x,
            2.0 * y,
            2.0 * z,
            1.0,
        ]);
        scatter += row * row.transpose();
    }
    let eigen = SymmetricEigen::new(scatter);
    let v = eigen
        .eigenvectors
        .column(eigen.eigenvalues.imin())
        .into_owned();
    // p^T A p + 2 g . p + j = 0, the sign so that A's trace is positive.
    let sign = if v[0] + v[1] + v[2] < 0.0 { -1.0 } else { 1.0 };
    let v = v * sign;
    let a = Matrix3::new(v[0], v[3], v[4], v[3], v[1], v[5], v[4], v[5], v[2]);
    let g = Vector3::new(v[6], v[7], v[8]);
    let a_inv = a
        .try_inverse()
        .ok_or("the quadric is not an ellipsoid (singular)")?;
    let p0 = -(a_inv * g);
    let k = (p0.transpose() * a * p0)[0] - v[9];
    let shape = a / k;
    let e = SymmetricEigen::new(shape);
    // Not `<= 0`: a NaN eigenvalue is no ellipsoid either.
    if e.eigenvalues.min().partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Err("the quadric is not an ellipsoid".into());
    }
    // Back in the readings' units: (m - b)^T (shape / s^2) (m - b) = 1.
    let b = c + p0 * s;
    let lambdas = e.eigenvalues / (s * s);
    let radius = lambdas.iter().product::<f64>().powf(-1.0 / 6.0);
    let root = lambdas.map(|l| l.sqrt() * radius);
    let w = e.eigenvectors * Matrix3::from_diagonal(&root) * e.eigenvectors.transpose();
    let w = (w + w.transpose()) / 2.0;
    if root.max() / root.min() > MAX_CONDITION {
        return Err(format!(
            "the ellipsoid is too elongated for a soft iron (condition {:.2}, at most \
             {MAX_CONDITION})",
            root.max() / root.min()
        ));
    }
    Ok(([b.x, b.y, b.z], from_matrix(&w)))
}

/// The radius, its residuals' RMS and the hard iron's standard deviations of `cal` on the
/// readings (`params` fitted: 4 for the sphere, 9 for the ellipsoid).
fn judge(readings: &[[f64; 3]], cal: &Calibration, params: usize) -> (f64, f64, [f64; 3]) {
    let n = readings.len() as f64;
    let corrected: Vec<Vector3<f64>> = readings
        .iter()
        .map(|m| Vector3::from(cal.apply(m)))
        .collect();
    let radius = corrected.iter().map(|v| v.norm()).sum::<f64>() / n;
    let ss: f64 = corrected.iter().map(|v| (v.norm() - radius).powi(2)).sum();
    let w = to_matrix(&cal.soft_iron);
    // r_i = |W (m - b)| - r: d/db = -W^T u, d/dr = -1.
    let mut jtj = SMatrix::<f64, 4, 4>::zeros();
    for v in &corrected {
        let u = v / v.norm().max(f64::MIN_POSITIVE);
        let db = -(w.transpose() * u);
        let row = SMatrix::<f64, 4, 1>::new(db.x, db.y, db.z, -1.0);
        jtj += row * row.transpose();
    }
    let s2 = ss / (n - params as f64).max(1.0);
    let sd = jtj.try_inverse().map_or([f64::INFINITY; 3], |cov| {
        [0, 1, 2].map(|i| (cov[(i, i)] * s2).sqrt())
    });
    (radius, (ss / n).sqrt(), sd)
}

/// Hard and soft iron from readings through a rotation (any unit, the same throughout): the
/// ellipsoid where the coverage allows it, else the hard iron alone, else refused (see the
/// module documentation). Readings that are not finite are left out.
pub fn fit(readings: &[[f64; 3]]) -> Result<MagCal, MagCalError> {
    let readings: Vec<[f64; 3]> = readings
        .iter()
        .copied()
        .filter(|m| m.iter().all(|v| v.is_finite()))
        .collect();
    if readings.len() < MIN_READINGS {
        return Err(MagCalError::TooFew(readings.len()));
    }
    // A band first, about the readings' mean: a circle's sphere fit is singular or meaningless.
    let (mean, _) = centre_scale(&readings);
    let rough = coverage(&readings, &[mean.x, mean.y, mean.z]);
    if rough.spread < HARD_MIN_SPREAD {
        return Err(MagCalError::Band(rough));
    }
    let b0 = sphere(&readings)?;
    let cover = coverage(&readings, &b0);
    if cover.spread < HARD_MIN_SPREAD {
        return Err(MagCalError::Band(cover));
    }
    let soft_allowed = cover.spread >= SOFT_MIN_SPREAD && cover.cells >= SOFT_MIN_CELLS;
    let full = if soft_allowed {
        ellipsoid(&readings)
    } else {
        let missing = cover.missing_faces();
        Err(format!(
            "the readings cover {:.0}% of the directions with spread {:.3} (the soft iron needs \
             {:.0}% and {SOFT_MIN_SPREAD}){}",
            cover.cells * 100.0,
            cover.spread,
            SOFT_MIN_CELLS * 100.0,
            if missing.is_empty() {
                String::new()
            } else {
                format!("; turn the sensor's {missing} axis towards the field too")
            }
        ))
    };
    let (cal, extent, why, params) = match full {
        Ok((b, w)) => (
            Calibration {
                hard_iron: b,
                soft_iron: w,
            },
            Extent::Full,
            None,
            9,
        ),
        Err(why) => (
            Calibration {
                hard_iron: b0,
                ..Calibration::IDENTITY
            },
            Extent::HardIron,
            Some(why),
            4,
        ),
    };
    let (field, rms_after, hard_iron_sd) = judge(&readings, &cal, params);
    let norms: Vec<f64> = readings.iter().map(|m| Vector3::from(*m).norm()).collect();
    let mean_norm = norms.iter().sum::<f64>() / norms.len() as f64;
    let rms_before =
        (norms.iter().map(|v| (v - mean_norm).powi(2)).sum::<f64>() / norms.len() as f64).sqrt();
    Ok(MagCal {
        cal,
        extent,
        why_hard_only: why,
        hard_iron_sd,
        field,
        rms_before,
        rms_after,
        coverage: coverage(&readings, &cal.hard_iron),
        readings: readings.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// Earth field 48 uT (20 north, 44 down) seen through attitudes `dirs` (unit directions of
    /// the field in the body, times its norm), distorted by `w_inv` and offset by `b`, with
    /// white noise of `noise` uT per axis.
    fn readings(
        dirs: &[[f64; 3]],
        b: [f64; 3],
        w_inv: &Mat3,
        noise: f64,
        seed: u64,
    ) -> Vec<[f64; 3]> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let normal = Normal::new(0.0, noise.max(1e-300)).unwrap();
        let h = (20f64 * 20.0 + 44.0 * 44.0).sqrt();
        dirs.iter()
            .map(|u| {
                let hb = u.map(|v| v * h);
                [0, 1, 2].map(|i| {
                    (0..3).map(|j| w_inv[i][j] * hb[j]).sum::<f64>()
                        + b[i]
                        + normal.sample(&mut rng)
                })
            })
            .collect()
    }

    /// Directions uniform on the sphere.
    fn everywhere(n: usize, seed: u64) -> Vec<[f64; 3]> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let z: f64 = rng.random_range(-1.0..1.0);
                let a: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                let r = (1.0 - z * z).sqrt();
                [r * a.cos(), r * a.sin(), z]
            })
            .collect()
    }

    /// The field turned about the body's `axis` (0, 1, 2) only, at a dip of 60 deg to the
    /// turning plane: a cone, the band of a single axis.
    fn band(n: usize, axis: usize) -> Vec<[f64; 3]> {
        (0..n)
            .map(|k| {
                let a = k as f64 * 0.05;
                let (s, c) = 60f64.to_radians().sin_cos();
                let mut u = [0.0; 3];
                u[axis] = s;
                u[(axis + 1) % 3] = c * a.cos();
                u[(axis + 2) % 3] = c * a.sin();
                u
            })
            .collect()
    }

    const SOFT_INV: Mat3 = [[1.08, 0.04, -0.02], [0.04, 0.93, 0.03], [-0.02, 0.03, 1.0]];
    const B: [f64; 3] = [12.0, -30.0, 7.5];

    fn close(a: &[f64; 3], b: &[f64; 3], tol: f64) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < tol)
    }

    /// Hard and soft iron through the whole sphere: b within a few sd, W the inverse of the
    /// distortion up to the scale that keeps the field's magnitude, the norm's spread gone.
    #[test]
    fn the_ellipsoid_is_found_with_its_offset_and_shape() {
        let m = readings(&everywhere(3000, 1), B, &SOFT_INV, 0.3, 2);
        let cal = fit(&m).unwrap();
        assert_eq!(cal.extent, Extent::Full, "{cal:?}");
        assert!(close(&cal.cal.hard_iron, &B, 0.2), "{cal:?}");
        assert!(
            cal.hard_iron_sd.iter().all(|s| *s > 0.001 && *s < 0.05),
            "{cal:?}"
        );
        for (i, (got, sd)) in cal.cal.hard_iron.iter().zip(cal.hard_iron_sd).enumerate() {
            let err = got - B[i];
            assert!(err.abs() < 5.0 * sd, "{i}: {err} {cal:?}");
        }
        // W W_inv is a multiple of the identity (its scale keeps det W = 1).
        let w = to_matrix(&cal.cal.soft_iron);
        let prod = w * to_matrix(&SOFT_INV);
        let scale = prod[(0, 0)];
        assert!(
            (prod - Matrix3::identity() * scale).abs().max() < 0.01,
            "{prod}"
        );
        assert!((w.determinant() - 1.0).abs() < 1e-9);
        assert!(cal.rms_before > 2.0 && cal.rms_after < 0.4, "{cal:?}");
        assert!(
            cal.coverage.cells > 0.95 && cal.coverage.spread > 0.25,
            "{cal:?}"
        );
        assert!(check_soft_iron(&cal.cal.soft_iron).is_ok());
        // Noise-free: exact.
        let exact = fit(&readings(&everywhere(500, 3), B, &SOFT_INV, 0.0, 4)).unwrap();
        assert!(close(&exact.cal.hard_iron, &B, 1e-6), "{exact:?}");
        assert!(exact.rms_after < 1e-6, "{exact:?}");
    }

    /// Turned about z only: refused, naming z; with a little of x and y as well (two bands),
    /// the hard iron alone, saying why; too few readings: refused.
    #[test]
    fn poor_coverage_is_refused_or_gives_the_hard_iron_alone() {
        for axis in 0..3 {
            let m = readings(&band(600, axis), B, &SOFT_INV, 0.3, 5);
            let e = fit(&m).unwrap_err();
            let text = e.to_string();
            let name = ["x", "y", "z"][axis];
            assert!(
                text.contains("only a band") && text.contains(&format!("its {name} axis")),
                "{text}"
            );
        }
        // Two bands, about z and about x: the offset is fixed, the ellipsoid is not.
        let mut dirs = band(600, 2);
        dirs.extend(band(600, 0));
        let m = readings(
            &dirs,
            B,
            &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            0.2,
            6,
        );
        let cal = fit(&m).unwrap();
        assert_eq!(cal.extent, Extent::HardIron, "{cal:?}");
        assert!(cal
            .why_hard_only
            .as_deref()
            .unwrap()
            .contains("soft iron needs"));
        assert_eq!(cal.cal.soft_iron, Calibration::IDENTITY.soft_iron);
        assert!(close(&cal.cal.hard_iron, &B, 0.3), "{cal:?}");
        assert_eq!(fit(&m[..10]).unwrap_err(), MagCalError::TooFew(10));
        let same = vec![[1.0, 2.0, 3.0]; 100];
        assert!(fit(&same).is_err());
    }

    #[test]
    fn a_soft_iron_is_checked() {
        assert!(check_soft_iron(&Calibration::IDENTITY.soft_iron).is_ok());
        let not_symmetric = [[1.0, 0.2, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(check_soft_iron(&not_symmetric)
            .unwrap_err()
            .contains("symmetric"));
        let negative = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(check_soft_iron(&negative)
            .unwrap_err()
            .contains("positive definite"));
        let stretched = [[5.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(check_soft_iron(&stretched)
            .unwrap_err()
            .contains("condition"));
        let nan = [[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(check_soft_iron(&nan).unwrap_err().contains("finite"));
    }
}
