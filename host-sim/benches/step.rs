//! `cargo bench -p host-sim --bench step`: host cost of one control step, and
//! the simulator's speed (one simulated second of the closed-loop prototype;
//! the real-time factor is 1 s divided by the measured time).
//!
//! The step is fed a recorded-style sample stream (a slow sine on every
//! counter) in joint closed-loop mode, so every stage of the control path runs.

use cable_joint::trajectory::Trajectory;
use cable_joint::units::{AdcCode, GratingCount, MagneticCount, MotorCount};
use cable_joint::{Command, Config, Controller, Mode, RawSample};
use criterion::{black_box, criterion_group, criterion_main, Criterion};

fn samples(n: usize) -> Vec<RawSample> {
    (0..n)
        .map(|k| {
            let t = k as f32 / 2000.0;
            let s = libm::sinf(2.0 * std::f32::consts::PI * t);
            RawSample {
                grating1: GratingCount((2000.0 * s) as i32),
                grating2: GratingCount((1900.0 * s) as i32),
                motor: MotorCount((12_000.0 * s) as i32 as u16),
                magnetic: MagneticCount((300.0 * s) as i32 as u16),
                current: AdcCode(2048 + (100.0 * s) as u16),
            }
        })
        .collect()
}

fn bench_step(c: &mut Criterion) {
    let input = samples(4096);
    let mut ctl = Controller::new(Config::default()).expect("default config is valid");
    ctl.set_command(Command {
        mode: Mode::JointClosedLoop,
        trajectory: Trajectory::Sine {
            offset_rad: 0.0,
            amplitude_rad: 0.5,
            freq_hz: 1.0,
        },
    });
    let mut k = 0usize;
    c.bench_function("controller_step", |b| {
        b.iter(|| {
            let out = ctl.step(black_box(&input[k & 4095]));
            k += 1;
            black_box(out)
        })
    });
}

fn bench_sim(c: &mut Criterion) {
    use host_sim::plant::PlantParams;
    use host_sim::sim::{NullRecorder, Sim};
    let command = Command {
        mode: Mode::JointClosedLoop,
        trajectory: Trajectory::Sine {
            offset_rad: 0.0,
            amplitude_rad: 0.5,
            freq_hz: 0.5,
        },
    };
    let mut group = c.benchmark_group("simulator");
    group.sample_size(10);
    group.bench_function("one_simulated_second", |b| {
        b.iter_batched(
            || {
                let mut sim = Sim::new(PlantParams::default(), Config::default(), 1).expect("sim");
                sim.set_command(command);
                sim
            },
            |mut sim| black_box(sim.run_for(1.0, &mut NullRecorder)),
            criterion::BatchSize::LargeInput,
        )
    });
    group.finish();
}

criterion_group!(benches, bench_step, bench_sim);
criterion_main!(benches);
