//! The magnetometer's hard-iron offset, learnt from the rotation the sensor sees: pure maths.
//!
//! A hard-iron offset `b` is a field fixed in the body (a magnet or magnetised steel that moves
//! with the sensor): the reading is `m = C^T h + b`, with `C` the body-to-earth rotation and
//! `h` the earth's field. With `C` known up to a slow heading offset (the 6D attitude), every
//! reading says `C (m - b) = h`, linear in `b` and `h`. Over a window the least-squares fit
//! needs only sums ([`Sums`]): `n`, `sum C`, `sum m`, `sum C m`, `sum |m|^2`. Eliminating `h`
//! leaves `M b = r` with `M = n I - (sum C)^T (sum C) / n`: `M / n` is 0 without rotation and
//! I after rotation through every direction, so its least eigenvalue says how much of `b` the
//! rotation showed ([`Fit::diversity`]), and `b`'s standard deviation is the fit's residual
//! over the square root of that eigenvalue ([`Fit::sd`]: white noise assumed, so a lower bound;
//! the caller asks for much more than its own threshold).

/// A 3x3 matrix, rows first.
pub type Mat3 = [[f64; 3]; 3];

/// `a . b`.
pub fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a x b`.
pub fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `m v`.
pub fn mat_vec(m: &Mat3, v: &[f64; 3]) -> [f64; 3] {
    [dot(&m[0], v), dot(&m[1], v), dot(&m[2], v)]
}

/// The rotation matrix of a unit quaternion (w, x, y, z): body to earth.
pub fn rotation(q: [f64; 4]) -> Mat3 {
    let [w, x, y, z] = q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// The least eigenvalue of a symmetric 3x3 matrix (the trigonometric closed form).
fn least_eigenvalue(a: &Mat3) -> f64 {
    let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    let trace = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
    if off <= 1e-30 * (trace * trace).max(f64::MIN_POSITIVE) {
        return a[0][0].min(a[1][1]).min(a[2][2]);
    }
    let d = [a[0][0] - trace, a[1][1] - trace, a[2][2] - trace];
    let p = ((d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + 2.0 * off) / 6.0).sqrt();
    let b = [
        [d[0] / p, a[0][1] / p, a[0][2] / p],
        [a[1][0] / p, d[1] / p, a[1][2] / p],
        [a[2][0] / p, a[2][1] / p, d[2] / p],
    ];
    let det = b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1])
        - b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0])
        + b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]);
    let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
    // The three are trace + 2p cos(phi + 2k pi / 3); k = 1 gives the least.
    trace + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos()
}

/// `m^-1 v` by Cramer's rule; None if `m` is singular.
fn solve(m: &Mat3, v: &[f64; 3]) -> Option<[f64; 3]> {
    let c0 = cross(&m[1], &m[2]);
    let det = dot(&m[0], &c0);
    if det.abs() <= f64::MIN_POSITIVE || !det.is_finite() {
        return None;
    }
    // The inverse's columns are the rows' cross products over the determinant.
    let c1 = cross(&m[2], &m[0]);
    let c2 = cross(&m[0], &m[1]);
    Some([0, 1, 2].map(|i| (c0[i] * v[0] + c1[i] * v[1] + c2[i] * v[2]) / det))
}

/// The sums of the hard-iron fit over a window (exponentially forgotten by the caller).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sums {
    /// Weight: the number of readings.
    pub n: f64,
    /// Sum of the body-to-earth rotations.
    pub c: Mat3,
    /// Sum of the readings, body frame.
    pub m: [f64; 3],
    /// Sum of the readings in the earth frame.
    pub cm: [f64; 3],
    /// Sum of the readings' squared norms.
    pub mm: f64,
}

/// What the fit of a window says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fit {
    /// The offset, body frame, in the readings' units.
    pub b: [f64; 3],
    /// Its standard deviation along its worst direction (white noise assumed).
    pub sd: f64,
    /// The least eigenvalue of `M / n`: 0 without rotation, 1 after every direction.
    pub diversity: f64,
    /// The mean squared residual `|C (m - b) - h|^2` with this `b`.
    pub residual: f64,
}

impl Sums {
    /// One reading `m` (body) at the rotation `c`, with `cm = c m` already at hand.
    pub fn add_reading(&mut self, c: &Mat3, m: &[f64; 3], cm: &[f64; 3]) {
        self.n += 1.0;
        for (row, add) in self.c.iter_mut().zip(c) {
            for (x, y) in row.iter_mut().zip(add) {
                *x += y;
            }
        }
        for i in 0..3 {
            self.m[i] += m[i];
            self.cm[i] += cm[i];
        }
        self.mm += dot(m, m);
    }

    /// Every sum times `keep` (exponential forgetting).
    pub fn fade(&mut self, keep: f64) {
        self.n *= keep;
        self.c = self.c.map(|row| row.map(|x| x * keep));
        self.m = self.m.map(|x| x * keep);
        self.cm = self.cm.map(|x| x * keep);
        self.mm *= keep;
    }

    /// `other` added.
    pub fn add(&mut self, other: &Sums) {
        self.n += other.n;
        for i in 0..3 {
            for j in 0..3 {
                self.c[i][j] += other.c[i][j];
            }
            self.m[i] += other.m[i];
            self.cm[i] += other.cm[i];
        }
        self.mm += other.mm;
    }

    /// The mean field in the earth frame with the offset `b` removed.
    pub fn field(&self, b: &[f64; 3]) -> [f64; 3] {
        let cb = mat_vec(&self.c, b);
        [0, 1, 2].map(|i| (self.cm[i] - cb[i]) / self.n)
    }

    /// The mean squared spread of `C (m - b)` about its mean: how far the field was from
    /// constant in the earth frame with the offset `b` (0 for an empty window).
    pub fn spread(&self, b: &[f64; 3]) -> f64 {
        if self.n <= 0.0 {
            return 0.0;
        }
        let h = self.field(b);
        let mean_sq = (self.mm - 2.0 * dot(b, &self.m) + self.n * dot(b, b)) / self.n;
        (mean_sq - dot(&h, &h)).max(0.0)
    }

    /// The least-squares offset of the window, if the rotation showed any of it.
    pub fn fit(&self) -> Option<Fit> {
        let n = self.n;
        if n <= 0.0 {
            return None;
        }
        // M = n I - C^T C / n, r = sum m - C^T (sum C m) / n, with C = sum C.
        let c = &self.c;
        let mut m = [[0.0; 3]; 3];
        let mut r = self.m;
        for i in 0..3 {
            for j in 0..3 {
                let ctc = c[0][i] * c[0][j] + c[1][i] * c[1][j] + c[2][i] * c[2][j];
                m[i][j] = if i == j { n } else { 0.0 } - ctc / n;
            }
            r[i] -= (c[0][i] * self.cm[0] + c[1][i] * self.cm[1] + c[2][i] * self.cm[2]) / n;
        }
        let least = least_eigenvalue(&m);
        let diversity = least / n;
        // NaN-safe: a NaN diversity is no rotation either.
        if diversity.is_nan() || diversity <= 1e-6 {
            return None;
        }
        let b = solve(&m, &r)?;
        let residual = self.spread(&b);
        Some(Fit {
            b,
            sd: (residual.max(1e-300) / least).sqrt(),
            diversity,
            residual,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rotation of `angle` about the unit `axis`, as a quaternion (w, x, y, z).
    fn about(axis: [f64; 3], angle: f64) -> [f64; 4] {
        let s = (angle / 2.0).sin();
        [(angle / 2.0).cos(), axis[0] * s, axis[1] * s, axis[2] * s]
    }

    #[test]
    fn the_least_eigenvalue_is_found() {
        // diag(1, 2, 3) turned by a rotation: the least is 1.
        let r = rotation(about([0.6, 0.0, 0.8], 0.9));
        let d = [1.0, 2.0, 3.0];
        let mut a = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                a[i][j] = (0..3).map(|k| r[i][k] * d[k] * r[j][k]).sum();
            }
        }
        assert!((least_eigenvalue(&a) - 1.0).abs() < 1e-9);
        assert_eq!(
            least_eigenvalue(&[[2.0, 0.0, 0.0], [0.0, 5.0, 0.0], [0.0, 0.0, 3.0]]),
            2.0
        );
        let x = solve(&a, &[1.0, 2.0, 3.0]).unwrap();
        let back = mat_vec(&a, &x);
        assert!((back[0] - 1.0).abs() + (back[1] - 2.0).abs() + (back[2] - 3.0).abs() < 1e-9);
        assert_eq!(solve(&[[0.0; 3]; 3], &[1.0, 0.0, 0.0]), None);
    }

    fn mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        [
            a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
            a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
            a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
            a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
        ]
    }

    /// Readings of the field (0, 20, -40) through many rotations, with an offset: the fit
    /// finds the offset, and says how well; without rotation it finds nothing.
    #[test]
    fn an_offset_is_found_from_rotation_and_not_without() {
        let h = [0.0, 20.0, -40.0];
        let b = [3.0, -7.0, 12.0];
        let mut sums = Sums::default();
        let mut still = Sums::default();
        for k in 0..2000 {
            let t = k as f64 * 0.01;
            let q = about([0.0, 0.0, 1.0], t * 2.3);
            let tilt = about([1.0, 0.0, 0.0], (t * 0.7).sin() * 1.2);
            let q = mul(q, tilt);
            let c = rotation(q);
            // m = C^T h + b
            let m: [f64; 3] = [0, 1, 2].map(|i| (0..3).map(|j| c[j][i] * h[j]).sum::<f64>() + b[i]);
            sums.add_reading(&c, &m, &mat_vec(&c, &m));
            let c0 = rotation([1.0, 0.0, 0.0, 0.0]);
            let m0 = [h[0] + b[0], h[1] + b[1], h[2] + b[2]];
            still.add_reading(&c0, &m0, &mat_vec(&c0, &m0));
        }
        let fit = sums.fit().unwrap();
        for (got, want) in fit.b.iter().zip(b) {
            assert!((got - want).abs() < 1e-6, "{fit:?}");
        }
        assert!(fit.diversity > 0.1 && fit.residual < 1e-9, "{fit:?}");
        let field = sums.field(&fit.b);
        assert!((field[1] - 20.0).abs() < 1e-6 && (field[2] + 40.0).abs() < 1e-6);
        assert!(sums.spread(&[0.0; 3]) > 10.0);
        assert_eq!(still.fit(), None);
        assert_eq!(Sums::default().fit(), None);
    }
}
