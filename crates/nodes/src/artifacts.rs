//! Artifact types that flow between nodes, as newtypes over the algorithm crates' types (the
//! engine's `ArtifactType` is implemented here so the algorithm crates stay engine-free).

use vfxgraph_engine::artifact::codec::{put_f32s, put_u64, Reader};
use vfxgraph_engine::{ArtifactType, Context, NodeError, SeqIn};
use vfxgraph_imaging::Image;

/// A linear-light f32 image (`image`).
#[derive(Clone, Debug, PartialEq)]
pub struct ImageArt(pub Image);

impl ArtifactType for ImageArt {
    const NAME: &'static str = "image";
    const DOC: &'static str =
        "A linear-light f32 image: width × height × channels (1 gray, 3 RGB, 4 RGBA), rows top-down.";
    fn encode(&self, out: &mut Vec<u8>) {
        put_image(out, &self.0);
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

/// Appends image `img` as [`ImageArt`] encodes it (without a copy of the image).
pub(crate) fn put_image(out: &mut Vec<u8>, img: &Image) {
    put_u64(out, img.width as u64);
    put_u64(out, img.height as u64);
    put_u64(out, img.channels as u64);
    put_f32s(out, &img.data);
}

/// The images of sequence input `port`, with their frame numbers, in frame order.
pub(crate) fn image_sequence<'a>(
    ctx: &'a Context<'_>,
    port: SeqIn<ImageArt>,
) -> Result<Vec<(i64, &'a Image)>, NodeError> {
    Ok(images(ctx.get(port)?))
}

/// The images of a sequence of [`ImageArt`], with their frame numbers.
pub(crate) fn images(seq: Vec<(i64, &ImageArt)>) -> Vec<(i64, &Image)> {
    seq.into_iter().map(|(f, i)| (f, &i.0)).collect()
}

/// Newtype artifacts stored as canonical JSON (serde, no hash maps), one per
/// `Name(Inner), "type name", "type doc"[, check = fn(&Inner) -> Result<(), impl Display>];`
/// entry. A type registers with the first node whose ports carry it.
macro_rules! json_artifact {
    ($($(#[$doc:meta])* $name:ident($inner:ty), $type_name:expr, $type_doc:expr
       $(, check = $check:path)?);+ $(;)?) => {
        $(
        $(#[$doc])*
        #[derive(Clone, Debug, PartialEq)]
        pub struct $name(pub $inner);

        impl vfxgraph_engine::ArtifactType for $name {
            const NAME: &'static str = $type_name;
            const DOC: &'static str = $type_doc;
            fn encode(&self, out: &mut Vec<u8>) {
                vfxgraph_engine::artifact::encode_json(&self.0, out)
            }
            fn decode(bytes: &[u8]) -> Result<Self, String> {
                let value: $inner = vfxgraph_engine::artifact::decode_json(bytes)?;
                $($check(&value).map_err(|e| e.to_string())?;)?
                Ok($name(value))
            }
        }
        )+
    };
}
pub(crate) use json_artifact;

json_artifact! {
    /// Camera intrinsics K (`intrinsics`).
    IntrinsicsArt(vfxgraph_geometry::Intrinsics), "intrinsics",
    "Camera intrinsics K: f1, f2, skew, principal point (pixels), optional image size.";
    /// A calibrated camera K[R|t] (`camera`).
    CameraArt(vfxgraph_geometry::Camera), "camera",
    "A calibrated camera K[R|t]: maps world X to pixels K(RX + t), looking down +z.";
    /// Pixel positions (`points2d`).
    Points2dArt(vfxgraph_geometry::Points2d), "points2d",
    "A list of image points (pixels, origin at the top-left pixel centre, y down).";
    /// World points (`points3d`).
    Points3dArt(vfxgraph_geometry::Points3d), "points3d",
    "A list of 3D points in world coordinates.";
    /// The cameras of a sequence, one [R|t] per frame (`camera_path`).
    CameraPathArt(vfxgraph_geometry::formats::CameraPath), "camera_path",
    "The extrinsics [R|t] of every solved frame of a shot (intrinsics travel separately).";
    /// A point cloud with track ids and errors (`point_cloud`).
    PointCloudArt(vfxgraph_geometry::points::PointCloud), "point_cloud",
    "Reconstructed 3D points, each with the id of its feature track and its RMS error (px).";
    /// Indices into another list (`indices`).
    IndicesArt(Vec<usize>), "indices",
    "A list of indices into another artifact's list (e.g. the inliers of a fit).";
    /// Any report of figures, as a JSON document (`report`).
    ReportArt(serde_json::Value), "report",
    "A report of figures (errors, inliers, timings) as a JSON document.";
}

impl ReportArt {
    /// The report of a typed report struct (its serde form).
    pub fn of<T: serde::Serialize>(report: &T) -> Result<Self, NodeError> {
        Ok(ReportArt(serde_json::to_value(report)?))
    }

    /// The report read back as the typed report `T` it was made from (the fields `T` names,
    /// checked; others ignored).
    pub fn parse<T: serde::de::DeserializeOwned>(&self) -> Result<T, String> {
        T::deserialize(&self.0).map_err(|e| e.to_string())
    }
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
