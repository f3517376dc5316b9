//! Per-stage cycle stamps for [`Controller::step_timed`](crate::Controller::step_timed).
//!
//! On hardware the counter is the DWT cycle counter; under QEMU with
//! `-icount shift=0,sleep=off` it is TIM2 running at 1 GHz of virtual time,
//! whose delta is the number of guest instructions (TOOLCHAIN.md).

use crate::controller::{Stage, StageTimer};

/// A free-running 32-bit counter (wrapping differences are taken).
pub trait CycleCounter {
    /// Current count.
    fn now(&mut self) -> u32;
}

impl<C: CycleCounter + ?Sized> CycleCounter for &mut C {
    #[inline(always)]
    fn now(&mut self) -> u32 {
        (**self).now()
    }
}

/// A counter that always reads zero (host replay, where cycles mean nothing).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoCycles;

impl CycleCounter for NoCycles {
    #[inline(always)]
    fn now(&mut self) -> u32 {
        0
    }
}

/// Records the duration of each stage of a step: sensing, JAE, DOB, cascade.
#[derive(Debug)]
pub struct StageStamps<C> {
    counter: C,
    last: u32,
    /// Counts spent in sensing, JAE, DOB and cascade (in that order).
    pub stages: [u32; 4],
}

impl<C: CycleCounter> StageStamps<C> {
    /// Stamps over `counter`, all stages zero.
    pub fn new(counter: C) -> Self {
        Self {
            counter,
            last: 0,
            stages: [0; 4],
        }
    }

    /// Stage durations saturated to 16 bits (the telemetry field).
    pub fn stages_u16(&self) -> [u16; 4] {
        self.stages.map(|c| c.min(u16::MAX as u32) as u16)
    }
}

impl<C: CycleCounter> StageTimer for StageStamps<C> {
    #[inline(always)]
    fn mark(&mut self, stage: Stage) {
        let now = self.counter.now();
        let slot = match stage {
            Stage::Start => None,
            Stage::Sensing => Some(0),
            Stage::Jae => Some(1),
            Stage::Dob => Some(2),
            Stage::Cascade => Some(3),
        };
        if let Some(s) = slot.and_then(|i| self.stages.get_mut(i)) {
            *s = now.wrapping_sub(self.last);
        }
        self.last = now;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Config, Controller, RawSample};

    /// A counter that advances by a growing step per read, across the wrap.
    struct Ramp {
        value: u32,
        step: u32,
    }

    impl CycleCounter for Ramp {
        fn now(&mut self) -> u32 {
            self.value = self.value.wrapping_add(self.step);
            self.step += 10;
            self.value
        }
    }

    #[test]
    fn stages_are_differences_between_marks_even_across_the_wrap() {
        let mut c = Controller::new(Config::default()).unwrap();
        let mut ramp = Ramp {
            value: u32::MAX - 20,
            step: 10,
        };
        let mut stamps = StageStamps::new(&mut ramp);
        c.step_timed(&RawSample::default(), &mut stamps);
        // Reads: start (+10), sensing (+20), JAE (+30), DOB (+40), cascade (+50).
        assert_eq!(stamps.stages, [20, 30, 40, 50]);
        assert_eq!(stamps.stages_u16(), [20, 30, 40, 50]);
        let big = StageStamps {
            counter: NoCycles,
            last: 0,
            stages: [70_000, 1, 2, 3],
        };
        assert_eq!(big.stages_u16(), [65_535, 1, 2, 3]);
    }
}
