//! Saving a param edit into the graph file: the YAML text of the one value is replaced, byte
//! for byte everything else stays (comments, layout, other values). The value's place comes
//! from the engine's spanned YAML tree ([`vfxgraph_engine::yaml::parse`], saphyr-parser
//! spans); the new file is checked to load and to give the param exactly the edited value
//! before it replaces the old one (written beside it, then renamed: atomic).

use std::path::Path;

use vfxgraph_engine::yaml::{self, Yaml};

fn entry<'a>(map: &'a Yaml, key: &str) -> Option<&'a Yaml> {
    map.as_map()?
        .iter()
        .find(|(k, _)| k.as_str() == Some(key))
        .map(|(_, v)| v)
}

/// `src` with the value of `nodes.NODE.params.PARAM` replaced by `value` (YAML text). A param
/// the file does not write (its default is used) cannot be replaced in place: an error.
pub fn replace_param(src: &str, node: &str, param: &str, value: &str) -> Result<String, String> {
    if value.contains('\n') || value.contains('\r') {
        return Err("a value saved to the graph file is one line".into());
    }
    let root = yaml::parse(src).map_err(|e| {
        format!(
            "the graph file does not parse ({}:{}): {}",
            e.span.line, e.span.col, e.message
        )
    })?;
    let n = entry(&root, "nodes")
        .and_then(|ns| entry(ns, node))
        .ok_or_else(|| format!("the graph file has no node `{node}`"))?;
    let params = entry(n, "params").ok_or_else(|| {
        format!("node `{node}` writes no `params:` in the file: add `{param}` there by hand")
    })?;
    let v = entry(params, param).ok_or_else(|| {
        format!(
            "node `{node}` does not write `{param}` in the file (its default is used): add it \
             there by hand, then save"
        )
    })?;
    let (start, end) = (v.span.offset, v.span.offset + v.span.len);
    if end > src.len() || !src.is_char_boundary(start) || !src.is_char_boundary(end) {
        return Err("the value's place in the file is not known".into());
    }
    let old = &src[start..end];
    if old.contains('\n') {
        return Err(format!(
            "`{node}.{param}` spans several lines in the file: edit it there by hand"
        ));
    }
    let mut out = String::with_capacity(src.len() + value.len());
    out.push_str(&src[..start]);
    out.push_str(value);
    out.push_str(&src[end..]);
    Ok(out)
}

/// Writes `text` to `file` atomically after `check` accepts a copy of it written beside
/// `file` (same folder, so relative paths in it resolve the same): the copy is renamed over
/// `file`, or removed when `check` fails.
pub fn write_checked(
    file: &Path,
    text: &str,
    check: impl FnOnce(&Path) -> Result<(), String>,
) -> Result<(), String> {
    let dir = file.parent().unwrap_or(Path::new("."));
    let name = file
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_else(|| "graph.yaml".into());
    let tmp = dir.join(format!(".{name}.{}.saving.yaml", std::process::id()));
    std::fs::write(&tmp, text).map_err(|e| format!("cannot write `{}`: {e}", tmp.display()))?;
    if let Err(e) = check(&tmp) {
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    std::fs::rename(&tmp, file).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        format!("cannot replace `{}`: {e}", file.display())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const SRC: &str = "# a graph\nversion: 1\nnodes:\n  grade:   # the grade\n    type: exposure\n    params: {stops: 0, mode: x}  # keep\n  blur:\n    type: blur\n    params:\n      radius: 2.5 # px\n      list: [1, 2]\n";

    #[test]
    fn replaces_only_the_value() {
        let out = replace_param(SRC, "grade", "stops", "1.5").unwrap();
        assert_eq!(out, SRC.replace("{stops: 0,", "{stops: 1.5,"));
        let out = replace_param(SRC, "blur", "radius", "4").unwrap();
        assert_eq!(out, SRC.replace("radius: 2.5 # px", "radius: 4 # px"));
        let out = replace_param(SRC, "blur", "list", "[3, 4, 5]").unwrap();
        assert_eq!(out, SRC.replace("[1, 2]", "[3, 4, 5]"));
    }

    #[test]
    fn refuses_what_is_not_there() {
        assert!(replace_param(SRC, "nope", "stops", "1").is_err());
        assert!(replace_param(SRC, "grade", "gain", "1").is_err());
        assert!(replace_param(SRC, "grade", "stops", "1\n2").is_err());
        assert!(replace_param("nodes: [", "a", "b", "1").is_err());
    }
}
