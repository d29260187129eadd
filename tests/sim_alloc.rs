//! The simulator allocates nothing per sample: a counting global allocator watches `next_sample`
//! after construction, with every noise process and motion on; and the accelerometer's
//! `next_reading` (attitude, vehicle force, noise) on the stop-and-go vehicle.

use driftless::sim::force::SimAccel;
use driftless::sim::{Motion, NoiseTerms, SimConfig, Simulator};
#[path = "support/alloc_counter.rs"]
mod alloc_counter;

#[test]
fn next_sample_does_not_allocate() {
    let cfg = SimConfig {
        terms: NoiseTerms {
            q: 1e-3,
            n: 0.01,
            b: 0.002,
            k: 1e-4,
            r: 1e-6,
            bias: 0.3,
        },
        rate_hz: 200.0,
        axes: 3,
        seed: 9,
        motion: Motion::Turn,
        lsb: Some(0.01),
    };
    let mut sim = Simulator::new(&cfg).unwrap();
    let (allocations, sum) = alloc_counter::allocations_during(|| {
        let mut sum = 0.0;
        for _ in 0..100_000 {
            let s = sim.next_sample();
            sum += s.measured[0] + s.truth[2];
        }
        sum
    });
    assert_eq!(allocations, 0, "allocations in next_sample");
    assert!(sum.is_finite());
}

#[test]
fn the_accelerometer_does_not_allocate() {
    let mut cfg = SimConfig::profile("adis16405").unwrap();
    cfg.motion = Motion::StopAndGo;
    let mut accel = SimAccel::new("adis16405", &cfg).unwrap().unwrap();
    let (allocations, sum) = alloc_counter::allocations_during(|| {
        let mut sum = 0.0;
        for _ in 0..100_000 {
            sum += accel.next_reading()[1];
        }
        sum
    });
    assert_eq!(allocations, 0, "allocations in next_reading");
    assert!(sum.is_finite());
}
