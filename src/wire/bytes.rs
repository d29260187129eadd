//! Our samples as their documented little-endian bytes, for transports that carry bytes
//! (Zenoh): [`WireBytes`].

use super::samples::{GyroSample, RawSample, GYRO_TYPE_NAME, RAW_TYPE_NAME};

/// A sample type that crosses a network as its documented little-endian bytes: the same layout
/// as in shared memory (`repr(C)`, no padding), written field by field so that it holds on any
/// host. What `driftless bridge` puts on Zenoh and takes back (docs/bridge.md).
pub trait WireBytes: Sized {
    /// Size of the encoded sample in bytes (its `size_of`).
    const SIZE: usize;
    /// The type name, as on iceoryx2 ([`RAW_TYPE_NAME`], [`GYRO_TYPE_NAME`]).
    const TYPE_NAME: &'static str;
    /// Append the sample's bytes to `out` (cleared first).
    fn encode(&self, out: &mut Vec<u8>);
    /// The sample from exactly [`WireBytes::SIZE`] bytes; `None` for any other length.
    fn decode(bytes: &[u8]) -> Option<Self>;
}

/// Little-endian reader over a byte slice of known length.
struct Le<'a>(&'a [u8]);

impl Le<'_> {
    fn u64(&mut self) -> u64 {
        let (head, rest) = self.0.split_at(8);
        self.0 = rest;
        u64::from_le_bytes(head.try_into().expect("8 bytes"))
    }
    fn u32(&mut self) -> u32 {
        let (head, rest) = self.0.split_at(4);
        self.0 = rest;
        u32::from_le_bytes(head.try_into().expect("4 bytes"))
    }
    fn f64s<const N: usize>(&mut self) -> [f64; N] {
        [(); N].map(|_| f64::from_bits(self.u64()))
    }
}

fn put_f64s(out: &mut Vec<u8>, v: &[f64]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

impl WireBytes for RawSample {
    const SIZE: usize = std::mem::size_of::<RawSample>();
    const TYPE_NAME: &'static str = RAW_TYPE_NAME;

    fn encode(&self, out: &mut Vec<u8>) {
        out.clear();
        out.extend_from_slice(&self.t_ns.to_le_bytes());
        out.extend_from_slice(&self.seq.to_le_bytes());
        put_f64s(out, &self.rate);
        out.extend_from_slice(&self.flags.to_le_bytes());
        out.extend_from_slice(&self.epoch.to_le_bytes());
        put_f64s(out, &self.accel);
        put_f64s(out, &self.mag);
    }

    fn decode(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != Self::SIZE {
            return None;
        }
        let mut r = Le(bytes);
        Some(RawSample {
            t_ns: r.u64(),
            seq: r.u64(),
            rate: r.f64s(),
            flags: r.u32(),
            epoch: r.u32(),
            accel: r.f64s(),
            mag: r.f64s(),
        })
    }
}

impl WireBytes for GyroSample {
    const SIZE: usize = std::mem::size_of::<GyroSample>();
    const TYPE_NAME: &'static str = GYRO_TYPE_NAME;

    fn encode(&self, out: &mut Vec<u8>) {
        out.clear();
        out.extend_from_slice(&self.t_ns.to_le_bytes());
        out.extend_from_slice(&self.seq.to_le_bytes());
        out.extend_from_slice(&self.ingest_ns.to_le_bytes());
        put_f64s(out, &self.rate);
        put_f64s(out, &self.drift);
        put_f64s(out, &self.denoised);
        out.extend_from_slice(&self.flags.to_le_bytes());
        out.extend_from_slice(&self.epoch.to_le_bytes());
        put_f64s(out, &self.drift_std);
        put_f64s(out, &self.accel);
        put_f64s(out, &self.accel_std);
        put_f64s(out, &self.mag);
        out.extend_from_slice(&self.sensors.to_le_bytes());
        out.extend_from_slice(&self.reserved.to_le_bytes());
        put_f64s(out, &self.orientation);
        put_f64s(out, &self.orientation_std);
    }

    fn decode(bytes: &[u8]) -> Option<Self> {
        if bytes.len() != Self::SIZE {
            return None;
        }
        let mut r = Le(bytes);
        Some(GyroSample {
            t_ns: r.u64(),
            seq: r.u64(),
            ingest_ns: r.u64(),
            rate: r.f64s(),
            drift: r.f64s(),
            denoised: r.f64s(),
            flags: r.u32(),
            epoch: r.u32(),
            drift_std: r.f64s(),
            accel: r.f64s(),
            accel_std: r.f64s(),
            mag: r.f64s(),
            sensors: r.u32(),
            reserved: r.u32(),
            orientation: r.f64s(),
            orientation_std: r.f64s(),
        })
    }
}
