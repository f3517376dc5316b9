//! Tool payload identification and tool-end wrench estimation with a wrist
//! force/torque sensor (seed 001, Sect. 2.1–2.3, Eq. 1–12).
//!
//! # Model
//!
//! The sensor reads (seed Eq. 1)
//!
//! ```text
//! F_s = F_g + F_0 + F_u + F_e
//! ```
//!
//! with `F_g` the gravity and inertia wrench of the payload (gripper + tool),
//! `F_0` the zero drift, `F_u` slow sensor errors (creep, temperature drift)
//! and `F_e` the tool-end interaction wrench. Newton–Euler for the payload
//! (mass `m`, centre of mass `c`, inertia `I` about the sensor origin, all in
//! the sensor frame {S}) gives `F_g = A(a, alpha, omega, g) phi` (Eq. 2–6) with
//!
//! ```text
//! phi = [m, m c_x, m c_y, m c_z, I_xx, I_xy, I_xz, I_yy, I_yz, I_zz]
//! f = m (g - a) - alpha x (m c) - omega x (omega x (m c))
//! tau = (m c) x (g - a) - I alpha - omega x (I omega)
//! ```
//!
//! **Sign convention.** `F` is the wrench the payload exerts *on the sensor*:
//! a payload at rest reads `f = m g` (the weight, along gravity) and
//! `tau = m c x g`. This is how wrist sensors such as the ATI Gamma of the
//! KUKA data set report. The seed writes the reaction (`f = m a - m g ...`),
//! i.e. its `A` is the negative of [`regressor`]; the parameters are the same.
//!
//! `a` is the linear acceleration of the sensor origin and `g` the gravity
//! vector (pointing down, `|g| = 9.81 m/s²`), both in {S}. Only `g - a`
//! enters, which is what an accelerometer measures (with the opposite sign:
//! the specific force `a - g`), see [`Kinematics::from_specific_force`].
//!
//! The extended regressor `A_ext = [E_6 | A]` (Eq. 8) adds the six zero-drift
//! entries `F_0` as parameters; [`PayloadIdentifier`] solves Eq. 11 by
//! streaming least squares ([`crate::lsq::BatchLsq`], 6 rows per sample).
//!
//! # Creep and drift (instead of the seed's SNN, Sect. 2.3)
//!
//! Two interpretable per-axis terms may be added to the least-squares model,
//! each switched on per axis:
//!
//! * **creep** of the payload load: a fraction `rho_k` of every change of the
//!   payload wrench `L = A phi` on axis `k` shows up with a first-order delay
//!   `tau`: `F_u,k = -rho_k creep_tau(L_k)`, where `creep_tau(u) = u -
//!   lag_tau(u)` is the part of a change still to come
//!   ([`crate::effects::EffectKind::Creep`] of the
//!   project's effect library). After a load step `dL` the reading jumps by
//!   `(1 - rho) dL` and creeps to `dL` (strain-gauge creep for `rho > 0`). The
//!   column is driven by the *model's* payload load, not by the measured
//!   wrench: a sustained contact wrench is not washed out, and the column is
//!   zero-mean, so it does not compete with `F_0`. `L` needs the inertial
//!   parameters: the identifier takes them from a first fit without creep
//!   ([`IdentConfig::creep_load`]); the estimator uses its own.
//! * **drift**: `F_u,k = d_k t`, `t` the time since the state was reset
//!   ([`crate::effects::EffectKind::Time`]).
//!
//! The same [`CompState`] code computes these columns during identification
//! and in the estimator, so both see identical numbers.
//!
//! # Estimation
//!
//! [`PayloadModel::estimate`] returns `F_e = F_s - A_ext phi_ext - F_u` (Eq. 12)
//! in `f32`, allocation- and panic-free, for the control loop. The optional
//! [`OffsetTracker`] re-estimates `F_0` by recursive least squares while the
//! caller knows there is no contact, and holds it otherwise.
//!
//! ```
//! use cable_joint::payload::{regressor, Kinematics};
//! use nalgebra::{SVector, Vector3};
//! // A 1 kg payload 0.1 m along x, at rest, gravity along -z.
//! let k = Kinematics::static_pose(Vector3::new(0.0, 0.0, -9.81));
//! let phi = SVector::<f64, 10>::from_column_slice(&[1.0, 0.1, 0.0, 0.0, 0., 0., 0., 0., 0., 0.]);
//! let w = regressor(&k) * phi;
//! assert!((w[2] + 9.81).abs() < 1e-12);      // f = m g
//! assert!((w[4] - 0.981).abs() < 1e-12);     // tau_y = (m c x g)_y = -c_x m g_z
//! ```

use core::fmt;

use nalgebra::{Matrix3, RealField, SMatrix, SVector, Vector3};

use crate::effects::{EffectKind, Term, TermState};
use crate::lsq::{BatchLsq, Fit, LsqConfig, LsqError, Rls, RlsConfig};

/// A wrench `[f_x, f_y, f_z, tau_x, tau_y, tau_z]` in N and N·m, sensor frame.
pub type Wrench<T> = SVector<T, 6>;

/// Number of zero-drift parameters `F_0`.
pub const N_OFFSET: usize = 6;
/// Number of rigid-body parameters `phi` (Eq. 7).
pub const N_INERTIAL: usize = 10;
/// Number of parameters of the extended model (Eq. 8).
pub const N_EXT: usize = N_OFFSET + N_INERTIAL;
/// Largest number of least-squares columns: `F_0`, `phi`, 6 creep, 6 drift.
pub const MAX_COLS: usize = N_EXT + 12;

/// Names of the rigid-body parameters, in the order of `phi` (Eq. 7).
pub const INERTIAL_NAMES: [&str; N_INERTIAL] = [
    "m_kg",
    "mcx_kg_m",
    "mcy_kg_m",
    "mcz_kg_m",
    "ixx_kg_m2",
    "ixy_kg_m2",
    "ixz_kg_m2",
    "iyy_kg_m2",
    "iyz_kg_m2",
    "izz_kg_m2",
];

/// Names of the six wrench axes.
pub const AXIS_NAMES: [&str; 6] = ["fx", "fy", "fz", "tx", "ty", "tz"];

/// Kinematics of the sensor frame {S}, all vectors expressed in {S}.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kinematics<T: RealField + Copy> {
    /// Gravity vector (pointing down, about 9.81 m/s² long), m/s².
    pub gravity_m_s2: Vector3<T>,
    /// Linear acceleration of the sensor origin, m/s².
    pub accel_m_s2: Vector3<T>,
    /// Angular velocity, rad/s.
    pub omega_rad_s: Vector3<T>,
    /// Angular acceleration, rad/s².
    pub alpha_rad_s2: Vector3<T>,
}

impl<T: RealField + Copy> Kinematics<T> {
    /// At rest: gravity only.
    pub fn static_pose(gravity_m_s2: Vector3<T>) -> Self {
        Self {
            gravity_m_s2,
            accel_m_s2: Vector3::zeros(),
            omega_rad_s: Vector3::zeros(),
            alpha_rad_s2: Vector3::zeros(),
        }
    }

    /// From an accelerometer at the sensor origin: it measures the specific
    /// force `a - g` (reads `+|g|` upwards at rest). Only `g - a` enters the
    /// model, so this sets `gravity = -specific_force`, `accel = 0`.
    pub fn from_specific_force(
        specific_force_m_s2: Vector3<T>,
        omega_rad_s: Vector3<T>,
        alpha_rad_s2: Vector3<T>,
    ) -> Self {
        Self {
            gravity_m_s2: -specific_force_m_s2,
            accel_m_s2: Vector3::zeros(),
            omega_rad_s,
            alpha_rad_s2,
        }
    }

    /// The apparent gravity `g - a`, m/s².
    pub fn apparent_gravity_m_s2(&self) -> Vector3<T> {
        self.gravity_m_s2 - self.accel_m_s2
    }

    /// Whether every entry is finite.
    pub fn is_finite(&self) -> bool {
        [
            &self.gravity_m_s2,
            &self.accel_m_s2,
            &self.omega_rad_s,
            &self.alpha_rad_s2,
        ]
        .iter()
        .all(|v| v.iter().all(|x| x.is_finite()))
    }
}

/// `L(v)` with `L(v) [I_xx, I_xy, I_xz, I_yy, I_yz, I_zz]^T = I v`.
fn inertia_map<T: RealField + Copy>(v: &Vector3<T>) -> SMatrix<T, 3, 6> {
    let z = T::zero();
    #[rustfmt::skip]
    let m = SMatrix::<T, 3, 6>::new(
        v.x, v.y, v.z, z, z, z,
        z, v.x, z, v.y, v.z, z,
        z, z, v.x, z, v.y, v.z,
    );
    m
}

/// The Newton–Euler regressor `A(a, alpha, omega, g)` (seed Eq. 5–6, in the
/// sensor-load sign convention of the [module docs](self)): `F_g = A phi`.
pub fn regressor<T: RealField + Copy>(k: &Kinematics<T>) -> SMatrix<T, 6, N_INERTIAL> {
    let gam = k.apparent_gravity_m_s2();
    let w = &k.omega_rad_s;
    let al = &k.alpha_rad_s2;
    // f = m gam + C (m c),  C = -[alpha]x - (w w^T - |w|^2 E)
    let c = -al.cross_matrix() - (w * w.transpose() - Matrix3::identity() * w.norm_squared());
    // tau = -[gam]x (m c) - (L(alpha) + [w]x L(w)) I
    let t_mc = -gam.cross_matrix();
    let t_i = -(inertia_map(al) + w.cross_matrix() * inertia_map(w));
    let mut a = SMatrix::<T, 6, N_INERTIAL>::zeros();
    a.fixed_view_mut::<3, 1>(0, 0).copy_from(&gam);
    a.fixed_view_mut::<3, 3>(0, 1).copy_from(&c);
    a.fixed_view_mut::<3, 3>(3, 1).copy_from(&t_mc);
    a.fixed_view_mut::<3, 6>(3, 4).copy_from(&t_i);
    a
}

/// The extended regressor `A_ext = [E_6 | A]` (seed Eq. 8): `F = A_ext
/// [F_0; phi]`.
pub fn regressor_ext<T: RealField + Copy>(k: &Kinematics<T>) -> SMatrix<T, 6, N_EXT> {
    let mut a = SMatrix::<T, 6, N_EXT>::zeros();
    a.fixed_view_mut::<6, 6>(0, 0)
        .copy_from(&SMatrix::<T, 6, 6>::identity());
    a.fixed_view_mut::<6, N_INERTIAL>(0, N_OFFSET)
        .copy_from(&regressor(k));
    a
}

/// Why identification or estimation failed.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PayloadError {
    /// The least-squares solver refused (too few samples, rank deficiency,
    /// bad configuration).
    Lsq(LsqError),
    /// An input (kinematics, wrench or time step) was NaN or infinite; the
    /// state is unchanged.
    NonFinite,
    /// A configuration value is out of range.
    InvalidConfig {
        /// Name of the field.
        field: &'static str,
    },
}

impl From<LsqError> for PayloadError {
    fn from(e: LsqError) -> Self {
        PayloadError::Lsq(e)
    }
}

impl fmt::Display for PayloadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PayloadError::Lsq(e) => write!(f, "payload identification: {e}"),
            PayloadError::NonFinite => write!(f, "input holds NaN or infinity"),
            PayloadError::InvalidConfig { field } => write!(f, "invalid value for `{field}`"),
        }
    }
}

impl core::error::Error for PayloadError {}

/// Settings of the creep/drift terms (shared by identification and
/// estimation).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CompConfig {
    /// Creep time constant, s (`None`: no creep columns).
    pub creep_tau_s: Option<f32>,
    /// Axes with a creep column (used only with `creep_tau_s`).
    pub creep_axes: [bool; 6],
    /// Axes with a linear drift column.
    pub drift_axes: [bool; 6],
}

impl CompConfig {
    /// No compensation terms.
    pub const NONE: CompConfig = CompConfig {
        creep_tau_s: None,
        creep_axes: [false; 6],
        drift_axes: [false; 6],
    };

    /// Creep with time constant `tau_s` on every axis (and drift on every
    /// axis if `drift`).
    pub const fn all_axes(creep_tau_s: Option<f32>, drift: bool) -> Self {
        Self {
            creep_tau_s,
            creep_axes: [creep_tau_s.is_some(); 6],
            drift_axes: [drift; 6],
        }
    }

    /// Check the time constant.
    pub fn validate(&self) -> Result<(), PayloadError> {
        match self.creep_tau_s {
            Some(t) if !(t > 0.0 && t.is_finite()) => Err(PayloadError::InvalidConfig {
                field: "creep_tau_s",
            }),
            _ => Ok(()),
        }
    }

    /// Whether axis `k` has a creep column.
    pub fn creep_on(&self, k: usize) -> bool {
        self.creep_tau_s.is_some() && self.creep_axes.get(k).copied().unwrap_or(false)
    }

    /// Whether axis `k` has a drift column.
    pub fn drift_on(&self, k: usize) -> bool {
        self.drift_axes.get(k).copied().unwrap_or(false)
    }

    /// Number of least-squares columns these terms add (0 to 12).
    pub fn n_cols(&self) -> usize {
        (0..6)
            .map(|k| usize::from(self.creep_on(k)) + usize::from(self.drift_on(k)))
            .sum()
    }
}

/// State of the creep/drift columns: one lag per axis and the elapsed time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompState {
    lag: [TermState; 6],
    time: TermState,
}

/// The creep and drift columns of one sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompColumns {
    /// `-creep_tau(L_k) = lag_tau(L_k) - L_k` per axis (zero where off).
    pub creep: [f32; 6],
    /// Time since the reset, s (zero without drift).
    pub time_s: f32,
}

impl CompState {
    /// Forget the lags and restart the clock (the next sample initialises the
    /// lags settled on its load).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Compute the columns of one sample from the payload load `L = A phi`
    /// (no offsets) and advance the state. The caller checks finiteness
    /// first.
    pub fn update(&mut self, config: &CompConfig, load: &Wrench<f32>, dt_s: f32) -> CompColumns {
        let mut out = CompColumns::default();
        let signals: [f32; 6] = (*load).into();
        if let Some(tau_s) = config.creep_tau_s {
            for (k, (s, o)) in self.lag.iter_mut().zip(out.creep.iter_mut()).enumerate() {
                if config.creep_on(k) {
                    let term = Term::new(EffectKind::Creep { tau_s }, k as u8);
                    *o = -term.update(s, &signals, dt_s);
                }
            }
        }
        if config.drift_axes.iter().any(|d| *d) {
            let term = Term::new(EffectKind::Time { scale_s: 1.0 }, 0);
            out.time_s = term.update(&mut self.time, &signals, dt_s);
        }
        out
    }
}

/// Settings of [`PayloadIdentifier`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentConfig {
    /// Identify the six inertia-tensor entries. They need angular
    /// acceleration and velocity to be excited; with slow motions leave them
    /// out (fixed at zero), or the problem is rank deficient.
    pub inertia: bool,
    /// Creep/drift columns.
    pub comp: CompConfig,
    /// Inertial parameters whose payload load `A phi` drives the creep
    /// columns (from a fit without creep; ignored without creep).
    pub creep_load: [f64; N_INERTIAL],
    /// Row weights per axis (typically `1 / noise std`): forces in N and
    /// torques in N·m are put on a common footing. All finite and positive.
    pub axis_weight: [f64; 6],
    /// Solver settings.
    pub lsq: LsqConfig,
}

impl Default for IdentConfig {
    fn default() -> Self {
        Self {
            inertia: true,
            comp: CompConfig::NONE,
            creep_load: [0.0; N_INERTIAL],
            axis_weight: [1.0; 6],
            lsq: LsqConfig::default(),
        }
    }
}

impl IdentConfig {
    /// Number of active least-squares columns.
    pub fn n_cols(&self) -> usize {
        N_OFFSET + 4 + if self.inertia { 6 } else { 0 } + self.comp.n_cols()
    }

    /// Check the ranges.
    pub fn validate(&self) -> Result<(), PayloadError> {
        self.comp.validate()?;
        if self.creep_load.iter().any(|v| !v.is_finite()) {
            return Err(PayloadError::InvalidConfig {
                field: "creep_load",
            });
        }
        if self
            .axis_weight
            .iter()
            .any(|w| !(*w > 0.0 && w.is_finite()))
        {
            return Err(PayloadError::InvalidConfig {
                field: "axis_weight",
            });
        }
        Ok(())
    }
}

/// What one least-squares column of [`PayloadIdentifier`] holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Column {
    /// Zero drift of axis `k`.
    Offset(usize),
    /// Entry `j` of `phi` (Eq. 7).
    Inertial(usize),
    /// Creep fraction of axis `k`.
    Creep(usize),
    /// Drift rate of axis `k`.
    Drift(usize),
}

impl IdentConfig {
    /// The meaning of least-squares column `col` (`None` past the last).
    pub fn column(&self, col: usize) -> Option<Column> {
        let n_phi = if self.inertia { N_INERTIAL } else { 4 };
        if col < N_OFFSET {
            return Some(Column::Offset(col));
        }
        let mut c = col - N_OFFSET;
        if c < n_phi {
            return Some(Column::Inertial(c));
        }
        c -= n_phi;
        let creep = (0..6).filter(|&k| self.comp.creep_on(k));
        let drift = (0..6).filter(|&k| self.comp.drift_on(k));
        creep
            .map(Column::Creep)
            .chain(drift.map(Column::Drift))
            .nth(c)
    }
}

/// Identified parameters (all in SI units, sensor frame).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PayloadParams {
    /// Zero drift `F_0`, N and N·m.
    pub offset: [f64; 6],
    /// `phi` (Eq. 7): `m` kg, `m c` kg·m, `I` kg·m² (`I_xx, I_xy, I_xz, I_yy,
    /// I_yz, I_zz`, about the sensor origin).
    pub inertial: [f64; N_INERTIAL],
    /// Creep fractions `rho_k` (dimensionless).
    pub creep: [f64; 6],
    /// Drift rates `d_k`, N/s and N·m/s.
    pub drift_per_s: [f64; 6],
}

impl PayloadParams {
    /// Mass, kg.
    pub fn mass_kg(&self) -> f64 {
        self.inertial[0]
    }

    /// Centre of mass `c = (m c) / m`, m (`None` for a non-positive mass).
    pub fn com_m(&self) -> Option<[f64; 3]> {
        let m = self.inertial[0];
        if m > 0.0 && m.is_finite() {
            Some([
                self.inertial[1] / m,
                self.inertial[2] / m,
                self.inertial[3] / m,
            ])
        } else {
            None
        }
    }

    /// `[F_0; phi]` as one vector (Eq. 8).
    pub fn ext_vector(&self) -> SVector<f64, N_EXT> {
        let mut v = SVector::<f64, N_EXT>::zeros();
        v.iter_mut()
            .zip(self.offset.iter().chain(self.inertial.iter()))
            .for_each(|(d, s)| *d = *s);
        v
    }

    /// The wrench the model expects with no contact, without the creep and
    /// drift terms: `A_ext [F_0; phi]`.
    pub fn predict_ext(&self, k: &Kinematics<f64>) -> Wrench<f64> {
        regressor_ext(k) * self.ext_vector()
    }
}

/// The result of [`PayloadIdentifier::solve`].
#[derive(Clone, Debug, PartialEq)]
pub struct PayloadFit {
    /// Parameters (those not identified are zero).
    pub params: PayloadParams,
    /// Their standard deviations (zero for those not identified), from the
    /// weighted residual; optimistic when the residual is coloured.
    pub std_dev: PayloadParams,
    /// The raw least-squares result (column order: `F_0`, `m`, `m c`, the
    /// inertia if identified, creep if any, drift if any).
    pub lsq: Fit<MAX_COLS>,
    /// Samples (6 rows each).
    pub samples: u64,
}

/// Streaming identification of `[F_0; phi]` (and creep/drift) from
/// no-contact samples (seed Eq. 11).
#[derive(Clone, Debug, PartialEq)]
pub struct PayloadIdentifier {
    config: IdentConfig,
    lsq: BatchLsq<MAX_COLS>,
    comp: CompState,
    samples: u64,
}

impl PayloadIdentifier {
    /// An empty identifier.
    pub fn new(config: IdentConfig) -> Result<Self, PayloadError> {
        config.validate()?;
        Ok(Self {
            lsq: BatchLsq::new(config.n_cols(), config.lsq)?,
            config,
            comp: CompState::default(),
            samples: 0,
        })
    }

    /// The settings.
    pub fn config(&self) -> &IdentConfig {
        &self.config
    }

    /// Samples accumulated.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// The six weighted least-squares rows of one sample: `rows[k]` holds the
    /// `n_cols()` regressors of axis `k`, `y[k]` its weighted measurement.
    /// `comp` are the creep/drift columns of this sample.
    pub fn rows(
        config: &IdentConfig,
        kin: &Kinematics<f64>,
        measured: &Wrench<f64>,
        comp: &CompColumns,
    ) -> ([[f64; MAX_COLS]; 6], [f64; 6]) {
        let a = regressor(kin);
        let mut rows = [[0.0; MAX_COLS]; 6];
        let mut y = [0.0; 6];
        let n_phi = if config.inertia { N_INERTIAL } else { 4 };
        for (k, (row, yk)) in rows.iter_mut().zip(y.iter_mut()).enumerate() {
            let w = config.axis_weight.get(k).copied().unwrap_or(1.0);
            let mut col = 0;
            let mut put = |row: &mut [f64; MAX_COLS], v: f64| {
                if let Some(c) = row.get_mut(col) {
                    *c = w * v;
                }
                col += 1;
            };
            for j in 0..N_OFFSET {
                put(row, if j == k { 1.0 } else { 0.0 });
            }
            for j in 0..n_phi {
                put(row, a[(k, j)]);
            }
            for j in 0..6 {
                if config.comp.creep_on(j) {
                    let v = comp.creep.get(k).copied().unwrap_or(0.0);
                    put(row, if j == k { f64::from(v) } else { 0.0 });
                }
            }
            for j in 0..6 {
                if config.comp.drift_on(j) {
                    put(row, if j == k { f64::from(comp.time_s) } else { 0.0 });
                }
            }
            *yk = w * measured[k];
        }
        (rows, y)
    }

    /// Accumulate one no-contact sample (`dt_s`: time since the previous
    /// sample; ignored on the first). A non-finite input is rejected and
    /// leaves the identifier unchanged.
    pub fn push(
        &mut self,
        kin: &Kinematics<f64>,
        measured: &Wrench<f64>,
        dt_s: f64,
    ) -> Result<(), PayloadError> {
        if !kin.is_finite() || measured.iter().any(|v| !v.is_finite()) || !dt_s.is_finite() {
            return Err(PayloadError::NonFinite);
        }
        let load = regressor(kin) * SVector::<f64, N_INERTIAL>::from(self.config.creep_load);
        let load32: Wrench<f32> = load.map(|v| v as f32);
        let mut comp_state = self.comp;
        let comp = comp_state.update(&self.config.comp, &load32, dt_s as f32);
        let (rows, y) = Self::rows(&self.config, kin, measured, &comp);
        let mut lsq = self.lsq.clone();
        for (row, yk) in rows.iter().zip(y.iter()) {
            lsq.push(row, *yk)?;
        }
        self.lsq = lsq;
        self.comp = comp_state;
        self.samples += 1;
        Ok(())
    }

    /// Solve (Eq. 11): parameters with standard deviations and the condition
    /// number of the regressor.
    pub fn solve(&self) -> Result<PayloadFit, PayloadError> {
        let fit = self.lsq.solve()?;
        let mut params = PayloadParams::default();
        let mut std_dev = PayloadParams::default();
        let n_phi = if self.config.inertia { N_INERTIAL } else { 4 };
        let mut col = 0usize;
        let mut take = |dst: &mut f64, sd: &mut f64| {
            *dst = fit.params.get(col).copied().unwrap_or(0.0);
            *sd = fit.std_dev.get(col).copied().unwrap_or(0.0);
            col += 1;
        };
        for (p, s) in params.offset.iter_mut().zip(std_dev.offset.iter_mut()) {
            take(p, s);
        }
        for (p, s) in params
            .inertial
            .iter_mut()
            .zip(std_dev.inertial.iter_mut())
            .take(n_phi)
        {
            take(p, s);
        }
        for (k, (p, s)) in params
            .creep
            .iter_mut()
            .zip(std_dev.creep.iter_mut())
            .enumerate()
        {
            if self.config.comp.creep_on(k) {
                take(p, s);
            }
        }
        for (k, (p, s)) in params
            .drift_per_s
            .iter_mut()
            .zip(std_dev.drift_per_s.iter_mut())
            .enumerate()
        {
            if self.config.comp.drift_on(k) {
                take(p, s);
            }
        }
        Ok(PayloadFit {
            params,
            std_dev,
            lsq: fit,
            samples: self.samples,
        })
    }
}

/// The tool-end wrench estimator (configuration): identified parameters and
/// the creep/drift terms, in `f32` for the control loop.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PayloadModel {
    /// Zero drift `F_0`, N and N·m.
    pub offset: [f32; 6],
    /// `phi` (Eq. 7).
    pub inertial: [f32; N_INERTIAL],
    /// Creep/drift terms.
    pub comp: CompConfig,
    /// Creep fractions `rho_k`.
    pub creep: [f32; 6],
    /// Drift rates, N/s and N·m/s.
    pub drift_per_s: [f32; 6],
}

impl PayloadModel {
    /// From identified parameters and the compensation terms they were
    /// identified with.
    pub fn new(params: &PayloadParams, comp: CompConfig) -> Result<Self, PayloadError> {
        comp.validate()?;
        let m = Self {
            offset: params.offset.map(|v| v as f32),
            inertial: params.inertial.map(|v| v as f32),
            comp,
            creep: params.creep.map(|v| v as f32),
            drift_per_s: params.drift_per_s.map(|v| v as f32),
        };
        if m.offset
            .iter()
            .chain(m.inertial.iter())
            .chain(m.creep.iter())
            .chain(m.drift_per_s.iter())
            .any(|v| !v.is_finite())
        {
            return Err(PayloadError::NonFinite);
        }
        Ok(m)
    }

    /// The wrench the model expects with no contact: `A_ext [F_0; phi] +
    /// F_u`, advancing the creep/drift state with this sample's payload load.
    /// A non-finite input returns [`PayloadError::NonFinite`] and leaves the
    /// state unchanged.
    pub fn predict(
        &self,
        state: &mut CompState,
        kin: &Kinematics<f32>,
        dt_s: f32,
    ) -> Result<Wrench<f32>, PayloadError> {
        if !kin.is_finite() || !dt_s.is_finite() {
            return Err(PayloadError::NonFinite);
        }
        let phi = SVector::<f32, N_INERTIAL>::from(self.inertial);
        let mut f = regressor(kin) * phi;
        let cols = state.update(&self.comp, &f, dt_s);
        for (k, fk) in f.iter_mut().enumerate() {
            let off = self.offset.get(k).copied().unwrap_or(0.0);
            let rho = self.creep.get(k).copied().unwrap_or(0.0);
            let lag = cols.creep.get(k).copied().unwrap_or(0.0);
            let d = self.drift_per_s.get(k).copied().unwrap_or(0.0);
            *fk += off + rho * lag + d * cols.time_s;
        }
        Ok(f)
    }

    /// The tool-end interaction wrench `F_e = F_s - A_ext phi_ext - F_u`
    /// (seed Eq. 12).
    pub fn estimate(
        &self,
        state: &mut CompState,
        kin: &Kinematics<f32>,
        measured: &Wrench<f32>,
        dt_s: f32,
    ) -> Result<Wrench<f32>, PayloadError> {
        if measured.iter().any(|v| !v.is_finite()) {
            return Err(PayloadError::NonFinite);
        }
        Ok(measured - self.predict(state, kin, dt_s)?)
    }
}

/// Recursive re-estimation of the zero drift `F_0` while no contact is known
/// (one scalar RLS per axis on the estimator's output); with contact the
/// correction is held.
#[derive(Clone, Debug, PartialEq)]
pub struct OffsetTracker {
    rls: [Rls<1>; 6],
}

impl OffsetTracker {
    /// A tracker with zero correction. `config.forgetting` sets the memory
    /// (about `1 / (1 - lambda)` samples).
    pub fn new(config: RlsConfig) -> Result<Self, PayloadError> {
        let r = Rls::<1>::new(config)?;
        Ok(Self {
            rls: [r.clone(), r.clone(), r.clone(), r.clone(), r.clone(), r],
        })
    }

    /// The current correction to subtract from the estimator's output.
    pub fn correction(&self) -> Wrench<f32> {
        Wrench::<f32>::from_fn(|k, _| self.rls.get(k).map_or(0.0, |r| r.params()[0]))
    }

    /// Corrected wrench `F_e - correction`; when `no_contact`, the estimate
    /// `F_e` (which should be zero) first updates the correction.
    pub fn process(&mut self, estimate: &Wrench<f32>, no_contact: bool) -> Wrench<f32> {
        if no_contact {
            for (r, e) in self.rls.iter_mut().zip(estimate.iter()) {
                r.update(&[1.0], *e);
            }
        }
        estimate - self.correction()
    }

    /// Forget the correction.
    pub fn reset(&mut self) {
        self.rls.iter_mut().for_each(Rls::reset);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The seed's Eq. 6 written out entry by entry (its sign convention:
    /// the wrench on the tool, `f = m a - m g + ...`).
    #[allow(clippy::too_many_arguments)]
    fn seed_table(a: [f64; 3], g: [f64; 3], w: [f64; 3], al: [f64; 3]) -> SMatrix<f64, 6, 10> {
        let [ax, ay, az] = a;
        let [gx, gy, gz] = g;
        let [wx, wy, wz] = w;
        let [alx, aly, alz] = al;
        #[rustfmt::skip]
        let m = SMatrix::<f64, 6, 10>::from_row_slice(&[
            ax - gx, -wy * wy - wz * wz, wx * wy - alz, wx * wz + aly, 0., 0., 0., 0., 0., 0.,
            ay - gy, wx * wy + alz, -wx * wx - wz * wz, wy * wz - alx, 0., 0., 0., 0., 0., 0.,
            az - gz, wx * wz - aly, wy * wz + alx, -wy * wy - wx * wx, 0., 0., 0., 0., 0., 0.,
            0., 0., az - gz, -ay + gy, alx, -wx * wz + aly, wx * wy + alz, -wy * wz, wy * wy - wz * wz, wy * wz,
            0., -az + gz, 0., ax - gx, wx * wz, wy * wz + alx, wz * wz - wx * wx, aly, -wx * wy + alz, -wx * wz,
            0., ay - gy, -ax + gx, 0., -wx * wy, wx * wx - wy * wy, alx - wy * wz, wx * wy, wx * wz + aly, alz,
        ]);
        m
    }

    #[test]
    fn regressor_is_the_seeds_table_negated() {
        let cases = [
            (
                [0.3, -1.2, 0.7],
                [0.0, 0.0, -9.81],
                [0.4, -0.9, 1.3],
                [2.0, 0.5, -1.5],
            ),
            (
                [-2.0, 0.1, 0.0],
                [3.0, -9.0, 1.5],
                [-1.1, 0.2, 0.6],
                [-0.3, 4.0, 0.8],
            ),
        ];
        for (a, g, w, al) in cases {
            let k = Kinematics {
                gravity_m_s2: Vector3::from(g),
                accel_m_s2: Vector3::from(a),
                omega_rad_s: Vector3::from(w),
                alpha_rad_s2: Vector3::from(al),
            };
            let ours = regressor(&k);
            let seed = seed_table(a, g, w, al);
            for i in 0..6 {
                for j in 0..10 {
                    assert!(
                        (ours[(i, j)] + seed[(i, j)]).abs() < 1e-12,
                        "entry ({i},{j}): ours {} seed {}",
                        ours[(i, j)],
                        seed[(i, j)]
                    );
                }
            }
        }
    }

    /// Direct Newton–Euler of a point-mass pair against the regressor: two
    /// masses rigidly attached, the wrench on the sensor from the sum of the
    /// individual `m_i (g - a_i)` and their moments.
    #[test]
    fn regressor_matches_point_masses() {
        let masses = [
            (0.7, Vector3::new(0.05, -0.02, 0.10)),
            (0.4, Vector3::new(-0.03, 0.04, 0.06)),
        ];
        let g = Vector3::new(1.0, -3.0, -9.2);
        let a0 = Vector3::new(0.4, 0.2, -0.5);
        let w = Vector3::new(0.8, -0.6, 1.1);
        let al = Vector3::new(-2.0, 1.5, 0.7);
        let mut f = Vector3::zeros();
        let mut tau = Vector3::zeros();
        let mut phi = SVector::<f64, 10>::zeros();
        for (m, r) in masses {
            let ai = a0 + al.cross(&r) + w.cross(&w.cross(&r));
            let fi = (g - ai) * m;
            f += fi;
            tau += r.cross(&fi);
            phi[0] += m;
            for j in 0..3 {
                phi[1 + j] += m * r[j];
            }
            // Inertia about the origin: m (|r|^2 E - r r^T).
            let i = (Matrix3::identity() * r.norm_squared() - r * r.transpose()) * m;
            let six = [
                i[(0, 0)],
                i[(0, 1)],
                i[(0, 2)],
                i[(1, 1)],
                i[(1, 2)],
                i[(2, 2)],
            ];
            for j in 0..6 {
                phi[4 + j] += six[j];
            }
        }
        let k = Kinematics {
            gravity_m_s2: g,
            accel_m_s2: a0,
            omega_rad_s: w,
            alpha_rad_s2: al,
        };
        let wr = regressor(&k) * phi;
        for j in 0..3 {
            assert!(
                (wr[j] - f[j]).abs() < 1e-12,
                "force {j}: {} vs {}",
                wr[j],
                f[j]
            );
            assert!(
                (wr[3 + j] - tau[j]).abs() < 1e-12,
                "torque {j}: {} vs {}",
                wr[3 + j],
                tau[j]
            );
        }
    }

    #[test]
    fn static_pose_gives_weight_and_moment() {
        let g = Vector3::new(0.0, -9.81, 0.0);
        let k = Kinematics::static_pose(g);
        let (m, c) = (1.3, Vector3::new(0.02, -0.01, 0.08));
        let mut phi = SVector::<f64, 10>::zeros();
        phi[0] = m;
        phi.fixed_rows_mut::<3>(1).copy_from(&(c * m));
        // Inertia must not matter at rest.
        phi.fixed_rows_mut::<6>(4)
            .copy_from_slice(&[0.01, 0.002, -0.001, 0.02, 0.003, 0.015]);
        let w = regressor(&k) * phi;
        let f = g * m;
        let tau = (c * m).cross(&g);
        for j in 0..3 {
            assert!((w[j] - f[j]).abs() < 1e-12, "f {j}");
            assert!((w[3 + j] - tau[j]).abs() < 1e-12, "tau {j}");
        }
        // The specific-force form of the same pose (accelerometer reads +g up).
        let k2 = Kinematics::from_specific_force(-g, Vector3::zeros(), Vector3::zeros());
        assert_eq!(regressor(&k2), regressor(&k));
        let ext = regressor_ext(&k);
        assert_eq!(ext[(3, 3)], 1.0);
        assert_eq!(ext[(3, 4)], 0.0);
    }

    #[test]
    fn bad_config_and_input_are_values() {
        let cfg = IdentConfig {
            comp: CompConfig::all_axes(Some(-1.0), false),
            ..IdentConfig::default()
        };
        assert_eq!(
            PayloadIdentifier::new(cfg).unwrap_err(),
            PayloadError::InvalidConfig {
                field: "creep_tau_s"
            }
        );
        let cfg = IdentConfig {
            axis_weight: [1.0, 1.0, 0.0, 1.0, 1.0, 1.0],
            ..IdentConfig::default()
        };
        assert!(PayloadIdentifier::new(cfg).is_err());
        let mut id = PayloadIdentifier::new(IdentConfig::default()).unwrap();
        let mut k = Kinematics::static_pose(Vector3::new(0.0, 0.0, -9.81));
        k.omega_rad_s[1] = f64::NAN;
        assert_eq!(
            id.push(&k, &Wrench::zeros(), 1e-3),
            Err(PayloadError::NonFinite)
        );
        assert_eq!(id.samples(), 0);
        assert!(matches!(
            id.solve(),
            Err(PayloadError::Lsq(LsqError::TooFewRows { .. }))
        ));
    }
}
