//! Several joints of one instrument, each with its own control path.
//!
//! Seed 000 builds its single joint as the unit of a four-joint wrist
//! (Sect. 2.2): every joint is a motor–cable–spring loop like the
//! prototype, with its own sensors, joint-angle estimate, cascade and force
//! estimate. [`Joints`] runs `N` such paths side by side, without
//! allocation (an array of [`Controller`]s, `N` a const generic), and adds
//! the one rule that belongs to the instrument rather than to a joint:
//!
//! * **a fault on any joint stops every drive within the same tick.** The
//!   joint that faulted has latched its fault and disabled its own drive;
//!   every other joint is put in [`Mode::Idle`] and its output of that tick
//!   rewritten as a disabled drive ([`Controller::stop`]). A jaw that keeps
//!   squeezing while its partner has lost its cable is not a safe state.
//! * **Nothing re-enables while a fault is latched anywhere**:
//!   [`Joints::set_command`] refuses every driven mode until the fault is
//!   cleared, and [`Joints::clear_fault`] refuses while the fault's cause
//!   persists ([`Controller::fault_cause_persists`]).
//!
//! Two joints can be declared a **pair of jaws** on one object
//! ([`Joints::set_pair`]): while both run a grip
//! ([`crate::trajectory::Trajectory::Grip`]), each tells the other its force
//! estimate and angle reference every tick, so together they regulate the clamp force
//! (Eq. 5, the mean of both jaws' squeeze) and stay level ([`crate::grip`]).
//!
//! The single joint is `N = 1`: [`Joints::step`] then runs exactly
//! [`Controller::step`], output for output (tested below).

use crate::controller::{Command, Controller, Mode, Output, RawSample};
use crate::fault::Fault;
use crate::grip::GripPartner;

/// Why [`Joints::set_command`] refused a command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Refused {
    /// There is no joint with this index.
    NoSuchJoint(usize),
    /// A pair of jaws needs two different joints.
    NotAPair(usize),
    /// A fault is latched on `joint`: no drive runs until it is cleared.
    Faulted {
        /// The joint whose fault is latched (the lowest index if several).
        joint: usize,
        /// Its fault.
        fault: Fault,
    },
    /// The fault's cause persists (the winding is still hot): it cannot be
    /// cleared yet.
    CausePersists(usize),
}

/// `N` joints, each with its own [`Controller`].
#[derive(Clone, Debug, PartialEq)]
pub struct Joints<const N: usize> {
    joints: [Controller; N],
    /// The jaws of a gripping pair, if declared.
    pair: Option<(usize, usize)>,
}

impl<const N: usize> Joints<N> {
    /// The joints, in the order their samples arrive in [`Joints::step`].
    /// Each controller carries its own configuration (its own identified
    /// parameters).
    pub fn new(joints: [Controller; N]) -> Self {
        Self { joints, pair: None }
    }

    /// Declare joints `a` and `b` the two jaws on one object (`None`: no
    /// pair). While both run a grip they regulate their mean force and
    /// stay level; otherwise each runs its own command alone.
    pub fn set_pair(&mut self, pair: Option<(usize, usize)>) -> Result<(), Refused> {
        if let Some((a, b)) = pair {
            for j in [a, b] {
                if j >= N {
                    return Err(Refused::NoSuchJoint(j));
                }
            }
            if a == b {
                return Err(Refused::NotAPair(a));
            }
        }
        // Every partner is forgotten: a jaw that left the pair must not
        // keep its old partner; the pair's jaws hear of each other again at
        // the next step.
        self.pair = pair;
        for c in &mut self.joints {
            c.set_grip_partner(None);
        }
        Ok(())
    }

    /// Joint `j`'s controller.
    pub fn joint(&self, j: usize) -> Option<&Controller> {
        self.joints.get(j)
    }

    /// Joint `j`'s controller, mutable (its configuration, homing).
    pub fn joint_mut(&mut self, j: usize) -> Option<&mut Controller> {
        self.joints.get_mut(j)
    }

    /// The latched fault of the lowest-numbered faulted joint, if any.
    pub fn fault(&self) -> Option<(usize, Fault)> {
        self.joints
            .iter()
            .enumerate()
            .find_map(|(j, c)| c.fault().map(|f| (j, f)))
    }

    /// Home every joint on its sample ([`Controller::set_origin`]).
    pub fn set_origin(&mut self, raw: &[RawSample; N]) {
        for (c, r) in self.joints.iter_mut().zip(raw) {
            c.set_origin(r);
        }
    }

    /// Give joint `j` a command. A driven mode is refused while any joint
    /// has a fault latched; [`Mode::Idle`] is always accepted.
    pub fn set_command(&mut self, j: usize, command: Command) -> Result<(), Refused> {
        if j >= N {
            return Err(Refused::NoSuchJoint(j));
        }
        if command.mode != Mode::Idle {
            if let Some((joint, fault)) = self.fault() {
                return Err(Refused::Faulted { joint, fault });
            }
        }
        self.joints[j].set_command(command);
        Ok(())
    }

    /// Clear joint `j`'s fault (it falls back to [`Mode::Idle`]), unless
    /// its cause persists.
    pub fn clear_fault(&mut self, j: usize) -> Result<(), Refused> {
        let c = self.joints.get_mut(j).ok_or(Refused::NoSuchJoint(j))?;
        if c.fault_cause_persists() {
            return Err(Refused::CausePersists(j));
        }
        c.clear_fault();
        Ok(())
    }

    /// One control tick of every joint, sample `j` to joint `j`. If any
    /// joint's fault is latched after its step, every other joint's drive is
    /// stopped in this same tick.
    pub fn step(&mut self, raw: &[RawSample; N]) -> [Output; N] {
        let mut out = [Output::default(); N];
        for ((o, c), r) in out.iter_mut().zip(self.joints.iter_mut()).zip(raw) {
            *o = c.step(r);
        }
        if let Some((a, b)) = self.pair {
            let both = self.joints[a].command().trajectory.is_grip()
                && self.joints[b].command().trajectory.is_grip();
            let partner = |o: &Output| {
                both.then_some(GripPartner {
                    force_n: o.est.f_ext_fused_n,
                    angle_ref_rad: o.est.theta_ref_rad,
                })
            };
            let (pa, pb) = (partner(&out[b]), partner(&out[a]));
            self.joints[a].set_grip_partner(pa);
            self.joints[b].set_grip_partner(pb);
        }
        if out.iter().any(|o| o.fault.is_some()) {
            for (o, c) in out.iter_mut().zip(self.joints.iter_mut()) {
                if o.fault.is_none() {
                    c.stop(o);
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trajectory::Trajectory;
    use crate::units::{AdcCode, GratingCount};
    use crate::Config;

    fn at_rest() -> RawSample {
        RawSample {
            current: AdcCode(2048),
            ..Default::default()
        }
    }

    fn hold(angle_rad: f32) -> Command {
        Command {
            mode: Mode::MotorPosition,
            trajectory: Trajectory::Hold { angle_rad },
        }
    }

    fn controller() -> Controller {
        Controller::new(Config::default()).unwrap()
    }

    /// N = 1 is the single joint: the same outputs, tick for tick, on a
    /// moving sample stream with a driven command.
    #[test]
    fn one_joint_steps_exactly_as_the_single_controller() {
        let mut single = controller();
        let mut joints = Joints::new([controller()]);
        single.set_command(hold(0.2));
        joints.set_command(0, hold(0.2)).unwrap();
        for k in 0..2000u32 {
            let mut raw = at_rest();
            raw.grating1 = GratingCount((k / 7) as i32);
            raw.grating2 = GratingCount(-((k / 11) as i32));
            raw.current = AdcCode(2048 + (k % 13) as u16);
            let a = single.step(&raw);
            let [b] = joints.step(&[raw]);
            assert_eq!(a, b, "tick {k}");
        }
    }

    /// A fault on joint 1 disables joint 0's and joint 2's drives in the
    /// tick it latches, and no driven command is taken until it is cleared.
    #[test]
    fn a_fault_on_one_joint_stops_every_drive_within_the_tick() {
        let mut joints = Joints::new([controller(), controller(), controller()]);
        for j in 0..3 {
            joints.set_command(j, hold(0.1)).unwrap();
        }
        let mut raw = [at_rest(); 3];
        let out = joints.step(&raw);
        assert!(out.iter().all(|o| o.drive_enable && o.current_ref_a != 0.0));
        raw[1].grating2 = GratingCount(5000); // 5 mm in one tick: impossible
        let out = joints.step(&raw);
        assert_eq!(
            out[1].fault,
            Some(Fault::EncoderJump(crate::fault::Sensor::Grating2))
        );
        let zero = joints.joint(0).unwrap().config().scales.dac_code(0.0);
        for o in &out {
            assert!(!o.drive_enable);
            assert_eq!(o.current_ref_a, 0.0);
            assert_eq!(o.dac, zero);
        }
        assert_eq!((out[0].mode, out[2].mode), (Mode::Idle, Mode::Idle));
        assert_eq!(
            joints.set_command(0, hold(0.1)),
            Err(Refused::Faulted {
                joint: 1,
                fault: Fault::EncoderJump(crate::fault::Sensor::Grating2)
            })
        );
        for _ in 0..100 {
            assert!(joints.step(&raw).iter().all(|o| !o.drive_enable));
        }
        joints.clear_fault(1).unwrap();
        assert_eq!(joints.fault(), None);
        joints.joint_mut(1).unwrap().set_origin(&raw[1]);
        joints.set_command(0, hold(0.1)).unwrap();
        let out = joints.step(&raw);
        assert!(out[0].drive_enable, "joint 0 runs again once cleared");
        assert!(
            !out[1].drive_enable && !out[2].drive_enable,
            "the others wait for a command"
        );
    }

    #[test]
    fn a_command_for_a_joint_that_does_not_exist_is_refused() {
        let mut joints = Joints::new([controller(), controller()]);
        assert_eq!(
            joints.set_command(2, hold(0.0)),
            Err(Refused::NoSuchJoint(2))
        );
        assert_eq!(joints.clear_fault(5), Err(Refused::NoSuchJoint(5)));
    }

    #[test]
    fn a_pair_needs_two_joints_that_exist() {
        let mut joints = Joints::new([controller(), controller(), controller()]);
        assert_eq!(joints.set_pair(Some((0, 3))), Err(Refused::NoSuchJoint(3)));
        assert_eq!(joints.set_pair(Some((1, 1))), Err(Refused::NotAPair(1)));
        assert_eq!(joints.set_pair(Some((1, 2))), Ok(()));
    }

    #[test]
    fn gripping_jaws_of_a_pair_hear_of_each_other_and_others_do_not() {
        let grip = Command {
            mode: Mode::MotorPosition,
            trajectory: Trajectory::Grip {
                force_n: 1.0,
                approach_rad_s: 0.1,
            },
        };
        let raw = [at_rest(); 3];
        let mut joints = Joints::new([controller(), controller(), controller()]);
        joints.set_origin(&raw);
        joints.set_pair(Some((0, 2))).unwrap();
        joints.set_command(0, grip).unwrap();
        joints.step(&raw);
        let partner = |joints: &Joints<3>, j: usize| joints.joint(j).unwrap().grip_partner();
        assert_eq!(partner(&joints, 0), None, "joint 2 does not grip yet");
        joints.set_command(2, grip).unwrap();
        let out = joints.step(&raw);
        let heard = partner(&joints, 0).expect("both grip: joint 0 hears of joint 2");
        assert_eq!(heard.force_n, out[2].est.f_ext_fused_n);
        assert_eq!(heard.angle_ref_rad, out[2].est.theta_ref_rad);
        assert_eq!(
            partner(&joints, 2).map(|p| p.angle_ref_rad),
            Some(out[0].est.theta_ref_rad)
        );
        assert_eq!(partner(&joints, 1), None, "joint 1 is not of the pair");
        joints.set_pair(Some((0, 1))).unwrap();
        assert_eq!(partner(&joints, 2), None, "joint 2 left the pair");
        joints.set_pair(None).unwrap();
        assert_eq!(partner(&joints, 0), None, "no pair, no partner");
    }
}
