//! Serde adapters that store bulk floats as one CBOR byte string of little-endian values.
//!
//! A CBOR array of a million floats is ~25 % larger and several times slower to read
//! than one byte string (measured in DESIGN.md). Every artifact field holding per-frame
//! numbers uses one of these through `#[serde(with = "mocap_io::bulk::...")]`.

use serde::{Deserialize, Deserializer, Serializer, de::Error as _};

fn to_bytes(values: impl Iterator<Item = f64>, len: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(len * 8);
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

fn from_bytes<'de, D: Deserializer<'de>>(d: D, group: usize) -> Result<Vec<f64>, D::Error> {
    let bytes: serde_bytes::ByteBuf = Deserialize::deserialize(d)?;
    if bytes.len() % (8 * group) != 0 {
        return Err(D::Error::custom(format!(
            "bulk float field has {} bytes, not a multiple of {}",
            bytes.len(),
            8 * group
        )));
    }
    Ok(bytes
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("chunks_exact(8) yields 8 bytes")))
        .collect())
}

/// `Vec<f64>` as one byte string.
pub mod f64s {
    use super::*;
    /// Serializes as little-endian bytes.
    pub fn serialize<S: Serializer>(v: &[f64], s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(&to_bytes(v.iter().copied(), v.len()))
    }
    /// Deserializes from little-endian bytes.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        from_bytes(d, 1)
    }
}

/// `Vec<[f64; 3]>` as one byte string (x, y, z interleaved).
pub mod vec3s {
    use super::*;
    /// Serializes as little-endian bytes.
    pub fn serialize<S: Serializer>(v: &[[f64; 3]], s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(&to_bytes(v.iter().flatten().copied(), v.len() * 3))
    }
    /// Deserializes from little-endian bytes.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<[f64; 3]>, D::Error> {
        let flat = from_bytes(d, 3)?;
        Ok(flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
    }
}

/// `Vec<[f64; 4]>` as one byte string (quaternions x, y, z, w).
pub mod vec4s {
    use super::*;
    /// Serializes as little-endian bytes.
    pub fn serialize<S: Serializer>(v: &[[f64; 4]], s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(&to_bytes(v.iter().flatten().copied(), v.len() * 4))
    }
    /// Deserializes from little-endian bytes.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<[f64; 4]>, D::Error> {
        let flat = from_bytes(d, 4)?;
        Ok(flat
            .chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect())
    }
}
