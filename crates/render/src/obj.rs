//! A small Wavefront OBJ reader for triangle meshes (geometry only): `v x y z [w]` vertices and
//! `f` faces whose corners are `i`, `i/t`, `i//n` or `i/t/n` (1-based, or negative = relative to
//! the last vertex); polygons are fanned into triangles from their first corner. Everything
//! else (`vt`, `vn`, `o`, `g`, `s`, `usemtl`, `mtllib`, `l`, `p`, comments) is ignored: the
//! scene assigns one material per OBJ file. Errors name the 1-based line.
//!
//! (A hand reader rather than the `tobj` crate: the renderer needs only positions and faces,
//! and this keeps errors at file:line and the dependency list short.)

use crate::math::Vec3;

/// An OBJ error at a 1-based line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{line}: {message}")]
pub struct ObjError {
    /// Line (1-based).
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

/// Reads the triangles of an OBJ text (see the module documentation).
pub fn parse_obj(text: &str) -> Result<Vec<[Vec3; 3]>, ObjError> {
    let mut verts: Vec<Vec3> = Vec::new();
    let mut tris = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let err = |message: String| ObjError { line, message };
        let content = raw.split('#').next().unwrap_or("");
        let mut it = content.split_whitespace();
        match it.next() {
            Some("v") => {
                let mut c = [0.0; 3];
                for (k, slot) in c.iter_mut().enumerate() {
                    let tok = it
                        .next()
                        .ok_or_else(|| err(format!("vertex needs 3 coordinates, got {k}")))?;
                    *slot = tok
                        .parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| err(format!("bad vertex coordinate `{tok}`")))?;
                }
                verts.push(Vec3::new(c[0], c[1], c[2]));
            }
            Some("f") => {
                let mut idx = Vec::new();
                for tok in it {
                    let first = tok.split('/').next().unwrap_or("");
                    let v: i64 = first
                        .parse()
                        .map_err(|_| err(format!("bad face corner `{tok}`")))?;
                    let n = verts.len() as i64;
                    let k = if v > 0 { v - 1 } else { n + v };
                    if v == 0 || k < 0 || k >= n {
                        return Err(err(format!(
                            "face corner `{tok}` refers to vertex {v}, but {n} vertices are defined so far"
                        )));
                    }
                    idx.push(k as usize);
                }
                if idx.len() < 3 {
                    return Err(err(format!(
                        "a face needs at least 3 corners, got {}",
                        idx.len()
                    )));
                }
                for j in 1..idx.len() - 1 {
                    tris.push([verts[idx[0]], verts[idx[j]], verts[idx[j + 1]]]);
                }
            }
            _ => {}
        }
    }
    Ok(tris)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_faces_in_every_corner_form() {
        let text = "# a unit square and a triangle\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0 1.0\n\
                    vt 0 0\nvn 0 0 1\nusemtl x\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -4//1 -3 -2\n";
        let t = parse_obj(text).unwrap();
        assert_eq!(t.len(), 3);
        assert_eq!(
            t[0],
            [
                Vec3::ZERO,
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0)
            ]
        );
        assert_eq!(t[1][2], Vec3::new(0.0, 1.0, 0.0));
        assert_eq!(t[2][0], Vec3::ZERO);
        let area: f64 = t[..2]
            .iter()
            .map(|t| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length())
            .sum();
        assert!((area - 1.0).abs() < 1e-12);
    }

    #[test]
    fn errors_name_the_line() {
        for (text, line, what) in [
            ("v 0 0 0\nv 1 0\n", 2, "3 coordinates"),
            ("v 0 0 0\nv 1 0 x\n", 2, "bad vertex"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 4\n",
                5,
                "refers to vertex 4",
            ),
            ("v 0 0 0\nf 1 1\n", 2, "at least 3"),
            ("v 0 0 0\nf 0 1 1\n", 2, "vertex 0"),
            ("v 0 0 0\nf a b c\n", 2, "bad face corner"),
        ] {
            let e = parse_obj(text).unwrap_err();
            assert_eq!(e.line, line, "{e}");
            assert!(e.message.contains(what), "{e}");
        }
    }
}
