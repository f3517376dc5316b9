//! Identification of the seed's models from logs (seed 000 Sect. 3.3 and 4):
//! motor damping `B_m`, the joint-angle estimator `chi_s` (Eq. 25-26) and the
//! no-load tension models A, B, C (Eq. 22-24, 27) with the seed's pruning by
//! `%sigma` to the simplified model C (Eq. 28-29). Results go into the
//! project's TOML configuration.
//!
//! ```text
//! host-sim identify --procedure bm      --log bm.csv      --config-out c.toml
//! host-sim identify --procedure jae     --log jae.csv     --validate jae2.csv --config-out c.toml
//! host-sim identify --procedure tension --log ten.csv     --config c.toml --config-out c.toml
//! host-sim identify --procedure all --log bm.csv jae.csv ten.csv \
//!     --validate bm2.csv jae2.csv ten2.csv --config-out c.toml --json ident.json
//! ```
//!
//! # Data
//!
//! Every log is first replayed through the core ([`crate::derive::TickReplay`]):
//! the regressors are the firmware's own signals (the tracking-observer
//! velocities and accelerations, the held friction signs of
//! [`SignMemory`](cable_joint::filter::SignMemory) with the configuration's switching speeds, the DOB's
//! outputs), not a second implementation of them.
//!
//! * **Filtering.** The DOB's outputs (`load_torque_nm`, `tension1_hat_n`) are
//!   `Q = g/(s+g)` of the torque balance (Eq. 18). The models are linear in
//!   their parameters, so `Q[W chi] = Q[W] chi`: by default every regressor
//!   column is passed through the same discrete `Q` (the core's
//!   [`LowPass1`](cable_joint::filter::LowPass1), same cut-off and rate) before the fit, which removes the
//!   observer's lag from the residual. This is also exactly what the firmware
//!   compares the model with (`tension1_model_n = Q[F_1']`).
//!   [`IdentOptions::filter_regressors`] `= false` gives the seed's plain fit.
//! * **Samples used.** The first [`IdentOptions::skip_start_s`] (0.2 s: the
//!   observers start at rest and the DOB's `Q` has a 16 ms time constant) and
//!   ticks the replay flags as faulted are dropped. For the tension models the
//!   seed notes larger errors at zero joint velocity (hysteresis: the cable is
//!   not rigid) and trusts the identification where the joint moves; ticks
//!   with `|theta'| <` [`IdentOptions::min_joint_vel_rad_s`] (default
//!   0.05 rad/s, about 3 °/s, `theta'` from the magnetic encoder through the
//!   core's tracking observer) are left out of the tension fits. A hold-off
//!   after each still tick ([`IdentOptions::holdoff_s`]) is available but off:
//!   on the simulator it removes the reversals, the only data that tells
//!   `sgn(x1')` from `sgn(x2')`, and the model it leaves fits the moving
//!   ticks but is 2.4 times worse over a whole validation run.
//! * **Offsets.** Every model carries a constant (seed 001's zero drift: no
//!   sensor is assumed to read zero at rest): `tau_0` for `B_m`, the JAE's
//!   `offset_rad`, `F_0` in the tension models. The `B_m` fit also carries
//!   the motor's Coulomb torque `tau_c sgn(phi')` (dropped by the `%sigma`
//!   rule when it is not there): leaving it out biases `B_m`.
//!
//! # Pruning (seed Sect. 4.2)
//!
//! Model C's parameters whose `%sigma = 100 std / |value|` exceeds
//! [`IdentOptions::max_pct_sigma`] (5 %) are dropped. The seed dropped all of
//! them at once ([`IdentOptions::prune_all_at_once`]); by default they are
//! dropped one at a time, the worst first, with a refit after each: when the
//! joint moves, `sgn(theta')`, `sgn(x1')` and `sgn(x2')` are nearly the same
//! column, each of them alone is poorly determined, and dropping all three
//! at once loses the friction altogether. The seed's data ended at
//! `[sgn x1', sgn x2', x2, 1] = [f_sc1, f_cp2, K_s, F_0]` (Eq. 29), which is
//! the structure the core evaluates; the configuration receives a refit on
//! those of the four that survived (a dropped one is written as 0), and kept
//! terms outside them are reported, not written.
//!
//! `%sigma` assumes independent residuals. At 2 kHz they are not (the DOB's
//! `Q`, the velocity loop's oscillation, unmodelled friction transients):
//! each fit reports the residual's correlation time
//! ([`correlation_time`](crate::stats::correlation_time)) and `%sigma eff`,
//! the `%sigma` scaled by its square root. The pruning keeps the seed's
//! rule on the plain `%sigma`.
//!
//! # Where things are
//!
//! The regressors and the seed's models as term lists (`terms.rs`), the
//! settings (`options.rs`), the replay of a log through the core
//! (`replay.rs`, [`Prepared`]), the design matrix, least squares and the
//! fit's report (`design.rs`), the pruning (`prune.rs`), one file per
//! procedure (`bm.rs`, `jae.rs` with `spring.rs` and `joint.rs`,
//! `tension.rs`), the seed's order over all three (`sequence.rs`) and the
//! results (`results.rs`). The command line is
//! [`crate::cli::identify`]; configuration files are [`crate::io::config`].

mod bm;
mod cable0;
mod design;
pub mod excite;
pub mod excite_wrist;
mod jae;
mod joint;
mod options;
mod prune;
mod replay;
mod results;
mod sequence;
mod spring;
mod tension;
mod terms;
mod weights;

pub use bm::{decoupled, identify_bm, identify_bm_with, validate_bm};
pub use cable0::{
    read_cable0_stiffness, Cable0Stiffness, MIN_STRETCHES as CABLE0_MIN_STRETCHES,
    MIN_TOTAL_S as CABLE0_MIN_TOTAL_S,
};
pub use jae::{identify_jae, identify_jae_with, validate_jae};
pub use joint::{
    Cable2Fit, JointFit, CABLE2_DECIMATED_SYSTEMATIC, CABLE2_MIN_TRAVEL_M, CABLE2_SYSTEMATIC,
    JOINT_DIFF_HALF_WINDOW_S, JOINT_MIN_INSTRUMENT_F, JOINT_MIN_TRAVEL_RAD,
};
pub use options::IdentOptions;
pub use replay::Prepared;
pub use results::{
    BmResult, FitReport, IdentifyReport, JaeResult, ParamEstimate, TensionResult, Validation,
};
pub use sequence::{identify_in_order, Runs};
pub use spring::{SpringFit, DECIMATED_ERROR, PER_TICK_SYSTEMATIC, SPRING_MIN_TRAVEL_M};
pub use tension::{identify_tension, identify_tension_with, validate_tension, LIMIT_CYCLE_SHARE};
use terms::term;
pub use terms::{
    nonnegative_by_physics, physically_required, ModelTerm, Regressor, BM_TERMS, JAE_TERMS,
    MAX_REGRESSORS, MODEL_A, MODEL_B, MODEL_C, SIMPLIFIED_C,
};
pub use weights::{
    calibrate_weights, parse_reference_steps, scale_disagreement, set_reference_steps, WeightsFit,
    WeightsHold, WeightsOptions,
};
