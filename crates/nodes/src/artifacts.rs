//! Artifact types that flow between nodes, as newtypes over the algorithm crates' types (the
//! engine's `ArtifactType` is implemented here so the algorithm crates stay engine-free).

use vfxgraph_engine::artifact::codec::{put_f32s, put_u64, Reader};
use vfxgraph_engine::{ArtifactType, Registry};
use vfxgraph_imaging::Image;

/// A linear-light f32 image (`image`).
#[derive(Clone, Debug, PartialEq)]
pub struct ImageArt(pub Image);

impl ArtifactType for ImageArt {
    const NAME: &'static str = "image";
    const DOC: &'static str =
        "A linear-light f32 image: width × height × channels (1 gray, 3 RGB, 4 RGBA), rows top-down.";
    fn encode(&self, out: &mut Vec<u8>) {
        let img = &self.0;
        put_u64(out, img.width as u64);
        put_u64(out, img.height as u64);
        put_u64(out, img.channels as u64);
        put_f32s(out, &img.data);
    }
    fn decode(bytes: &[u8]) -> Result<Self, String> {
        let mut r = Reader::new(bytes);
        let w = r.u64()? as usize;
        let h = r.u64()? as usize;
        let c = r.u64()? as usize;
        let data = r.f32s()?;
        r.finish()?;
        Image::from_vec(w, h, c, data)
            .map(ImageArt)
            .map_err(|e| e.to_string())
    }
}

/// Registers the artifact types of this crate.
pub fn register(r: &mut Registry) {
    r.register_artifact::<ImageArt>();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_round_trip_and_bad_bytes() {
        let img = Image::from_vec(2, 1, 3, vec![0.0, 0.5, 1.0, 2.0, -1.0, 1e9]).unwrap();
        let mut bytes = Vec::new();
        ImageArt(img.clone()).encode(&mut bytes);
        assert_eq!(ImageArt::decode(&bytes).unwrap().0, img);
        assert!(ImageArt::decode(&bytes[..bytes.len() - 1]).is_err());
        // Dimensions that disagree with the data are an error, not a panic.
        let mut bad = Vec::new();
        put_u64(&mut bad, 5);
        put_u64(&mut bad, 5);
        put_u64(&mut bad, 3);
        put_f32s(&mut bad, &[1.0]);
        assert!(ImageArt::decode(&bad).is_err());
    }
}
