//! Artifacts: the values that flow on a graph's edges.
//!
//! Every artifact type has a stable name, a canonical binary encoding and a content digest
//! (blake3 of the type name and that encoding). The engine never knows what an artifact *is*; node
//! crates register their types in the [`crate::Registry`].

use std::any::Any;
use std::fmt;
use std::sync::Arc;

/// A blake3 content digest.
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Digest(pub [u8; 32]);

impl Digest {
    /// Lower-case hex, 64 characters.
    pub fn to_hex(&self) -> String {
        blake3::Hash::from_bytes(self.0).to_hex().to_string()
    }

    /// Parses 64 hex characters.
    pub fn from_hex(s: &str) -> Option<Digest> {
        blake3::Hash::from_hex(s)
            .ok()
            .map(|h| Digest(*h.as_bytes()))
    }

    /// The first 12 hex characters, for display.
    pub fn short(&self) -> String {
        self.to_hex()[..12].to_string()
    }

    /// Digest of arbitrary bytes.
    pub fn of(bytes: &[u8]) -> Digest {
        Digest(*blake3::hash(bytes).as_bytes())
    }
}

impl fmt::Debug for Digest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Digest({})", self.short())
    }
}

impl fmt::Display for Digest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.to_hex())
    }
}

/// A type that can flow on an edge.
///
/// `encode` must be canonical: equal values give equal bytes, on every machine and thread count,
/// because the bytes' digest is what the cache keys on (early cutoff compares digests).
pub trait ArtifactType: Any + Send + Sync + Sized + 'static {
    /// Stable type name used in graph validation, cache entries and `vfxgraph describe`.
    const NAME: &'static str;
    /// One line describing the type.
    const DOC: &'static str = "";
    /// Appends the canonical encoding to `out`.
    fn encode(&self, out: &mut Vec<u8>);
    /// Decodes what [`ArtifactType::encode`] wrote.
    fn decode(bytes: &[u8]) -> Result<Self, String>;
}

/// Object-safe view of an artifact value.
pub trait DynArtifact: Any + Send + Sync {
    /// The type's stable name.
    fn type_name(&self) -> &'static str;
    /// Appends the canonical encoding.
    fn encode_into(&self, out: &mut Vec<u8>);
    /// For downcasting.
    fn as_any(&self) -> &dyn Any;
}

impl<T: ArtifactType> DynArtifact for T {
    fn type_name(&self) -> &'static str {
        T::NAME
    }
    fn encode_into(&self, out: &mut Vec<u8>) {
        self.encode(out)
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
}

/// An artifact value with its digest (computed once, when the value is made or loaded).
#[derive(Clone)]
pub struct Value {
    data: Arc<dyn DynArtifact>,
    digest: Digest,
}

impl fmt::Debug for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Value({}, {})", self.type_name(), self.digest.short())
    }
}

impl Value {
    /// Wraps a value, encoding it once to compute its digest. Returns the encoding too, since the
    /// store writes exactly those bytes.
    pub fn new_encoded<T: ArtifactType>(value: T) -> (Value, Vec<u8>) {
        let mut bytes = Vec::new();
        value.encode(&mut bytes);
        let digest = content_digest(T::NAME, &bytes);
        (
            Value {
                data: Arc::new(value),
                digest,
            },
            bytes,
        )
    }

    /// Wraps a value, computing its digest.
    pub fn new<T: ArtifactType>(value: T) -> Value {
        Self::new_encoded(value).0
    }

    /// A value whose digest the run sets later ([`Value::named`]): an uncached reader's
    /// output, named by its instance's key rather than by its content.
    pub(crate) fn unnamed<T: ArtifactType>(value: T) -> Value {
        Value {
            data: Arc::new(value),
            digest: Digest([0; 32]),
        }
    }

    /// The same value under `digest`.
    pub(crate) fn named(self, digest: Digest) -> Value {
        Value {
            data: self.data,
            digest,
        }
    }

    pub(crate) fn from_parts(data: Arc<dyn DynArtifact>, digest: Digest) -> Value {
        Value { data, digest }
    }

    /// The content digest.
    pub fn digest(&self) -> Digest {
        self.digest
    }

    /// The type's stable name.
    pub fn type_name(&self) -> &'static str {
        self.data.type_name()
    }

    /// The canonical encoding.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::new();
        self.data.encode_into(&mut out);
        out
    }

    /// The value, shared.
    pub fn data(&self) -> &Arc<dyn DynArtifact> {
        &self.data
    }

    /// Borrows the value as `T`, if it is one.
    pub fn get<T: ArtifactType>(&self) -> Option<&T> {
        self.data.as_any().downcast_ref::<T>()
    }
}

/// Digest of an encoded artifact: blake3 over the type name, a zero byte and the encoding.
pub fn content_digest(type_name: &str, bytes: &[u8]) -> Digest {
    let mut h = blake3::Hasher::new();
    h.update(type_name.as_bytes());
    h.update(&[0]);
    h.update(bytes);
    Digest(*h.finalize().as_bytes())
}

/// Digest of a sequence: the frame numbers and the per-element digests, in frame order.
pub fn sequence_digest<'a>(elements: impl IntoIterator<Item = (i64, &'a Digest)>) -> Digest {
    let mut h = blake3::Hasher::new();
    h.update(b"sequence\0");
    for (frame, d) in elements {
        h.update(&frame.to_le_bytes());
        h.update(&d.0);
    }
    Digest(*h.finalize().as_bytes())
}

/// A decoder registered for an artifact type.
pub(crate) type DecodeFn = fn(&[u8]) -> Result<Arc<dyn DynArtifact>, String>;

pub(crate) fn decoder<T: ArtifactType>() -> DecodeFn {
    |bytes| T::decode(bytes).map(|v| Arc::new(v) as Arc<dyn DynArtifact>)
}

/// Helpers for writing canonical encodings by hand: little-endian, length-prefixed.
pub mod codec {
    /// Appends a u64, little endian.
    pub fn put_u64(out: &mut Vec<u8>, v: u64) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends an i64, little endian.
    pub fn put_i64(out: &mut Vec<u8>, v: i64) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    /// Appends an f64's bits, little endian.
    pub fn put_f64(out: &mut Vec<u8>, v: f64) {
        out.extend_from_slice(&v.to_bits().to_le_bytes());
    }
    /// Appends a length-prefixed byte string.
    pub fn put_bytes(out: &mut Vec<u8>, b: &[u8]) {
        put_u64(out, b.len() as u64);
        out.extend_from_slice(b);
    }
    /// Appends a slice of f32 as little-endian bits, length-prefixed.
    pub fn put_f32s(out: &mut Vec<u8>, v: &[f32]) {
        put_u64(out, v.len() as u64);
        out.reserve(v.len() * 4);
        for x in v {
            out.extend_from_slice(&x.to_bits().to_le_bytes());
        }
    }

    /// A cursor over an encoding; every read checks bounds.
    pub struct Reader<'a> {
        bytes: &'a [u8],
        pos: usize,
    }

    impl<'a> Reader<'a> {
        /// Starts at the beginning of `bytes`.
        pub fn new(bytes: &'a [u8]) -> Self {
            Reader { bytes, pos: 0 }
        }
        fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
            let end = self
                .pos
                .checked_add(n)
                .filter(|&e| e <= self.bytes.len())
                .ok_or_else(|| format!("truncated encoding at byte {}", self.pos))?;
            let s = &self.bytes[self.pos..end];
            self.pos = end;
            Ok(s)
        }
        /// Reads a u64.
        pub fn u64(&mut self) -> Result<u64, String> {
            Ok(u64::from_le_bytes(
                self.take(8)?.try_into().expect("8 bytes"),
            ))
        }
        /// Reads an i64.
        pub fn i64(&mut self) -> Result<i64, String> {
            Ok(i64::from_le_bytes(
                self.take(8)?.try_into().expect("8 bytes"),
            ))
        }
        /// Reads an f64.
        pub fn f64(&mut self) -> Result<f64, String> {
            Ok(f64::from_bits(self.u64()?))
        }
        /// Reads a length-prefixed byte string.
        pub fn bytes(&mut self) -> Result<&'a [u8], String> {
            let n = usize::try_from(self.u64()?).map_err(|_| "length overflow".to_string())?;
            self.take(n)
        }
        /// Reads a length-prefixed f32 slice.
        pub fn f32s(&mut self) -> Result<Vec<f32>, String> {
            let n = usize::try_from(self.u64()?).map_err(|_| "length overflow".to_string())?;
            let raw = self.take(n.checked_mul(4).ok_or("length overflow")?)?;
            Ok(raw
                .chunks_exact(4)
                .map(|c| f32::from_bits(u32::from_le_bytes(c.try_into().expect("4 bytes"))))
                .collect())
        }
        /// Fails unless every byte was read.
        pub fn finish(&self) -> Result<(), String> {
            if self.pos == self.bytes.len() {
                Ok(())
            } else {
                Err(format!(
                    "{} trailing bytes in encoding",
                    self.bytes.len() - self.pos
                ))
            }
        }
    }
}

/// Serde-encoded artifacts: canonical as long as the type's serialization is (no hash maps).
/// JSON is used because it is stable across versions and readable in the store.
pub fn encode_json<T: serde::Serialize>(value: &T, out: &mut Vec<u8>) {
    serde_json::to_writer(out, value).expect("serializing to memory cannot fail");
}

/// Decodes [`encode_json`]'s output.
pub fn decode_json<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> Result<T, String> {
    serde_json::from_slice(bytes).map_err(|e| e.to_string())
}

/// Built-in scalar artifacts useful to any graph.
macro_rules! scalar_artifact {
    ($t:ty, $name:expr, $doc:expr) => {
        impl ArtifactType for $t {
            const NAME: &'static str = $name;
            const DOC: &'static str = $doc;
            fn encode(&self, out: &mut Vec<u8>) {
                encode_json(self, out)
            }
            fn decode(bytes: &[u8]) -> Result<Self, String> {
                decode_json(bytes)
            }
        }
    };
}
scalar_artifact!(f64, "float", "A 64-bit float.");
scalar_artifact!(i64, "int", "A 64-bit integer.");
scalar_artifact!(bool, "bool", "A boolean.");
scalar_artifact!(String, "string", "A UTF-8 string.");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digest_depends_on_type_and_bytes() {
        let a = Value::new(1.5f64);
        let b = Value::new(1.5f64);
        let c = Value::new(2.5f64);
        assert_eq!(a.digest(), b.digest());
        assert_ne!(a.digest(), c.digest());
        assert_ne!(
            content_digest("float", b"1"),
            content_digest("int", b"1"),
            "same bytes, other type"
        );
        assert_eq!(a.get::<f64>(), Some(&1.5));
        assert_eq!(a.get::<i64>(), None);
    }

    #[test]
    fn hex_round_trip() {
        let d = Digest::of(b"x");
        assert_eq!(Digest::from_hex(&d.to_hex()), Some(d));
    }

    #[test]
    fn codec_bounds() {
        let mut out = Vec::new();
        codec::put_f32s(&mut out, &[1.0, 2.0]);
        let mut r = codec::Reader::new(&out);
        assert_eq!(r.f32s().unwrap(), vec![1.0, 2.0]);
        r.finish().unwrap();
        let mut r = codec::Reader::new(&out[..5]);
        assert!(r.f32s().is_err());
    }
}
