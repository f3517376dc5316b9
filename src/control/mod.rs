//! The control path: what [`Controller::step`](crate::Controller::step) runs
//! every tick, a raw sample in, the current command and the estimates out.
//!
//! In the order of a tick:
//!
//! * [`controller`]: `step()` itself, the sensing (counter extension, jump and
//!   rail checks, scaling), the faults it raises, state apart from the
//!   prepared configuration;
//! * [`filter`]: the tracking observers that differentiate the sensors, the
//!   low-pass and sign memories the estimators share;
//! * [`jae`]: the joint-angle estimate;
//! * [`model`] and [`effects`]: the effect terms the residual loop added to
//!   the JAE and to the tension model, evaluated every tick ([`effects`] also
//!   holds the term kinds the host fits; their candidate library is in the
//!   host tool);
//! * [`dob`]: the no-load tension model and the disturbance observer;
//! * [`fusion`]: the fused force estimate and its bound;
//! * [`trajectory`] and [`probe`]: the reference, and the dither at a hold
//!   with its synchronous mean; [`grip`]: the admittance law that makes the
//!   reference of a force set point;
//! * [`cascade`]: the PD/PI cascade to the current reference.
//!
//! Beside the tick: [`joints`] runs `N` joints' control paths side by side
//! (one fault stops every drive), and [`wrist`] maps the joints' force
//! estimates to the jaws' tip forces and the clamp force (seed Eq. 1-5), with
//! [`wrist_dynamics`]'s rigid-body torque of the links (Eq. 3) taken out.
//!
//! Each module is also re-exported at the crate root under its name
//! (`cable_joint::dob` is `cable_joint::control::dob`), so the paths used
//! before this grouping still work.

pub mod cascade;
pub mod controller;
pub mod dob;
pub mod effects;
pub mod filter;
pub mod fusion;
pub mod grip;
pub mod jae;
pub mod joints;
pub mod model;
pub mod probe;
pub mod trajectory;
pub mod wrist;
pub mod wrist_dynamics;
