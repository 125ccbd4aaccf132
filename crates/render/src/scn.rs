//! The book's scene language (S3D `.scn`, book §9.13): a reader into [`Scene`] with
//! errors at line:column.
//!
//! Grammar (as the book's files use it): `scene{ items }` or `hdrscene{ items }`, optionally
//! followed by `;`. An item is `key = value` or a bare value; commas between items are
//! optional. A value is a number, a "string", a list `{v, v, …}` or a constructor
//! `name{ items }`. Comments: `#`, `//` and `/* */`. A stray `.` right after a number
//! (`kd = 1.0.` in the book's `modeling.scn`) is accepted.
//!
//! Constructors: `view{from, at, up, fov, imgw, imgh}` (S3D defaults (0,−5,0), origin,
//! (0,0,1), 90°, 320×240; fov is horizontal), `primobj{material, shape}`,
//! `polyobj{material, shape}`, `group{object = …}`, `sphere{center, radius}`,
//! `trilist{{v0,v1,v2}, …}`, `polylight{color, shape}`, `hdrdome{orig, south, hdrimg}`,
//! `plshadow{material, shape}`, `plastic{kd, ks, kt, se, d_col, s_col, ka, ir}`.
//!
//! ## How `plastic` and `polylight` map to physical quantities
//!
//! The book's tracer shades with kd·d_col + ks·(n·h)^se and no 1/π: read physically, its light
//! colours are radiance/π. We read kd·d_col as the diffuse albedo ρd, ks·s_col as the lobe's
//! albedo ρs (normalized Blinn–Phong, see [`crate::brdf::BlinnPhong`]), and multiply polylight
//! colours by π ([`SCN_LIGHT_SCALE`]): direct diffuse lighting then equals the book's image
//! exactly, interreflections are physical (no energy gain), and highlights are brighter by
//! π·C(e) (≈2.1 for se = 10). `se < 0` (the book's −1) is a perfect mirror of reflectance
//! ks·s_col, and the diffuse term is ignored, as the book's tracer does. Defaults follow S3D
//! (kd .9, ks 0, se 10, d_col white) except s_col, white here: S3D's default is black but the
//! book's tracer ignores s_col and colours highlights white. When ρd + ρs exceeds 1 in a
//! channel both are scaled down to conserve energy. `kt` (transmission) must be 0; `ka`, `ir`
//! are accepted and ignored (no ambient term, no refraction).

use std::f64::consts::PI;

use crate::brdf::{BlinnPhong, Brdf, Lambert, Mirror};
use crate::camera::Camera;
use crate::math::{Rgb, Vec3};
use crate::scene::{AreaLight, DomeSpec, Object, Scene, Shape};
use crate::shape::Sphere;

/// Factor applied to `polylight` colours to get radiance (see the module documentation).
pub const SCN_LIGHT_SCALE: f64 = PI;

/// A `.scn` error at a 1-based line and column.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{line}:{col}: {message}")]
pub struct ScnError {
    /// Line (1-based).
    pub line: usize,
    /// Column (1-based, in characters).
    pub col: usize,
    /// What is wrong.
    pub message: String,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Pos {
    line: usize,
    col: usize,
}

fn err<T>(pos: Pos, message: impl Into<String>) -> Result<T, ScnError> {
    Err(ScnError {
        line: pos.line,
        col: pos.col,
        message: message.into(),
    })
}

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Ident(String),
    Num(f64),
    Str(String),
    Open,
    Close,
    Eq,
    Comma,
    Semi,
    Eof,
}

fn lex(text: &str) -> Result<Vec<(Tok, Pos)>, ScnError> {
    let chars: Vec<char> = text.chars().collect();
    let mut toks = Vec::new();
    let (mut i, mut line, mut col) = (0usize, 1usize, 1usize);
    macro_rules! bump {
        () => {{
            if chars[i] == '\n' {
                line += 1;
                col = 1;
            } else {
                col += 1;
            }
            i += 1;
        }};
    }
    while i < chars.len() {
        let c = chars[i];
        let pos = Pos { line, col };
        if c.is_whitespace() {
            bump!();
        } else if c == '#' || (c == '/' && chars.get(i + 1) == Some(&'/')) {
            while i < chars.len() && chars[i] != '\n' {
                bump!();
            }
        } else if c == '/' && chars.get(i + 1) == Some(&'*') {
            bump!();
            bump!();
            loop {
                if i >= chars.len() {
                    return err(pos, "unterminated comment");
                }
                if chars[i] == '*' && chars.get(i + 1) == Some(&'/') {
                    bump!();
                    bump!();
                    break;
                }
                bump!();
            }
        } else if c == '{' || c == '}' || c == '=' || c == ',' || c == ';' {
            toks.push((
                match c {
                    '{' => Tok::Open,
                    '}' => Tok::Close,
                    '=' => Tok::Eq,
                    ',' => Tok::Comma,
                    _ => Tok::Semi,
                },
                pos,
            ));
            bump!();
        } else if c == '"' {
            bump!();
            let mut s = String::new();
            loop {
                if i >= chars.len() || chars[i] == '\n' {
                    return err(pos, "unterminated string");
                }
                if chars[i] == '"' {
                    bump!();
                    break;
                }
                s.push(chars[i]);
                bump!();
            }
            toks.push((Tok::Str(s), pos));
        } else if c.is_ascii_digit()
            || ((c == '-' || c == '+' || c == '.')
                && chars
                    .get(i + 1)
                    .is_some_and(|d| d.is_ascii_digit() || *d == '.'))
        {
            let mut s = String::new();
            if c == '-' || c == '+' {
                s.push(c);
                bump!();
            }
            let digits = |s: &mut String, i: &mut usize| {
                let mut n = 0;
                while *i < chars.len() && chars[*i].is_ascii_digit() {
                    s.push(chars[*i]);
                    *i += 1;
                    n += 1;
                }
                n
            };
            let start = i;
            let mut nd = digits(&mut s, &mut i);
            if i < chars.len() && chars[i] == '.' {
                s.push('.');
                i += 1;
                nd += digits(&mut s, &mut i);
            }
            if nd > 0 && i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
                let save = (i, s.len());
                s.push('e');
                i += 1;
                if i < chars.len() && (chars[i] == '-' || chars[i] == '+') {
                    s.push(chars[i]);
                    i += 1;
                }
                if digits(&mut s, &mut i) == 0 {
                    i = save.0;
                    s.truncate(save.1);
                }
            }
            // A stray '.' directly after a number (the book's `1.0.`).
            if nd > 0 && i < chars.len() && chars[i] == '.' && s.contains('.') {
                i += 1;
            }
            col += i - start;
            let v: f64 = match s.parse() {
                Ok(v) if nd > 0 => v,
                _ => return err(pos, format!("bad number `{s}`")),
            };
            toks.push((Tok::Num(v), pos));
        } else if c.is_alphabetic() || c == '_' {
            let mut s = String::new();
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                s.push(chars[i]);
                bump!();
            }
            toks.push((Tok::Ident(s), pos));
        } else {
            return err(pos, format!("unexpected character `{c}`"));
        }
    }
    toks.push((Tok::Eof, Pos { line, col }));
    Ok(toks)
}

#[derive(Clone, Debug)]
enum Val {
    Num(f64, Pos),
    Str(String, Pos),
    List(Vec<Val>, Pos),
    Call(Call),
}

#[derive(Clone, Debug)]
struct Call {
    name: String,
    pos: Pos,
    items: Vec<Item>,
}

#[derive(Clone, Debug)]
struct Item {
    key: Option<(String, Pos)>,
    val: Val,
}

impl Val {
    fn pos(&self) -> Pos {
        match self {
            Val::Num(_, p) | Val::Str(_, p) | Val::List(_, p) => *p,
            Val::Call(c) => c.pos,
        }
    }
    fn describe(&self) -> String {
        match self {
            Val::Num(v, _) => format!("the number {v}"),
            Val::Str(s, _) => format!("the string \"{s}\""),
            Val::List(..) => "a list".into(),
            Val::Call(c) => format!("`{}{{…}}`", c.name),
        }
    }
}

/// Deepest nesting of `{…}` accepted: the book's scenes nest 5 levels; a parser recursing once
/// per level would overflow a thread's stack on a few thousand `{`.
const MAX_DEPTH: usize = 64;

struct Parser {
    toks: Vec<(Tok, Pos)>,
    i: usize,
    depth: usize,
}

impl Parser {
    fn peek(&self) -> &(Tok, Pos) {
        &self.toks[self.i]
    }
    fn next(&mut self) -> (Tok, Pos) {
        let t = self.toks[self.i].clone();
        if self.i + 1 < self.toks.len() {
            self.i += 1;
        }
        t
    }
    fn expect_open(&mut self, what: &str) -> Result<Pos, ScnError> {
        match self.next() {
            (Tok::Open, p) => Ok(p),
            (t, p) => err(p, format!("expected `{{` after {what}, found {}", show(&t))),
        }
    }
    fn value(&mut self) -> Result<Val, ScnError> {
        if self.depth == MAX_DEPTH {
            return err(
                self.peek().1,
                format!("values nested deeper than {MAX_DEPTH} levels"),
            );
        }
        self.depth += 1;
        let v = self.value_inner();
        self.depth -= 1;
        v
    }
    fn value_inner(&mut self) -> Result<Val, ScnError> {
        match self.next() {
            (Tok::Num(v), p) => Ok(Val::Num(v, p)),
            (Tok::Str(s), p) => Ok(Val::Str(s, p)),
            (Tok::Open, p) => {
                let mut vals = Vec::new();
                loop {
                    match self.peek().0 {
                        Tok::Close => {
                            self.next();
                            break;
                        }
                        Tok::Comma => {
                            self.next();
                        }
                        Tok::Eof => return err(p, "this `{` is never closed"),
                        _ => vals.push(self.value()?),
                    }
                }
                Ok(Val::List(vals, p))
            }
            (Tok::Ident(name), p) => {
                let open = self.expect_open(&format!("`{name}`"))?;
                let items = self.items(open)?;
                Ok(Val::Call(Call {
                    name,
                    pos: p,
                    items,
                }))
            }
            (t, p) => err(p, format!("expected a value, found {}", show(&t))),
        }
    }
    /// Items up to and including the closing `}`.
    fn items(&mut self, open: Pos) -> Result<Vec<Item>, ScnError> {
        let mut items = Vec::new();
        loop {
            match self.peek().clone() {
                (Tok::Close, _) => {
                    self.next();
                    return Ok(items);
                }
                (Tok::Comma, _) | (Tok::Semi, _) => {
                    self.next();
                }
                (Tok::Eof, _) => return err(open, "this `{` is never closed"),
                (Tok::Ident(name), p) if self.toks[self.i + 1].0 == Tok::Eq => {
                    self.next();
                    self.next();
                    let val = self.value()?;
                    items.push(Item {
                        key: Some((name, p)),
                        val,
                    });
                }
                _ => {
                    let val = self.value()?;
                    items.push(Item { key: None, val });
                }
            }
        }
    }
}

fn show(t: &Tok) -> String {
    match t {
        Tok::Ident(s) => format!("`{s}`"),
        Tok::Num(v) => format!("the number {v}"),
        Tok::Str(s) => format!("\"{s}\""),
        Tok::Open => "`{`".into(),
        Tok::Close => "`}`".into(),
        Tok::Eq => "`=`".into(),
        Tok::Comma => "`,`".into(),
        Tok::Semi => "`;`".into(),
        Tok::Eof => "the end of the file".into(),
    }
}

fn num(v: &Val, what: &str) -> Result<f64, ScnError> {
    match v {
        Val::Num(x, _) => Ok(*x),
        other => err(
            other.pos(),
            format!("{what}: expected a number, found {}", other.describe()),
        ),
    }
}

fn vec3(v: &Val, what: &str) -> Result<Vec3, ScnError> {
    match v {
        Val::List(xs, p) => {
            if xs.len() != 3 {
                return err(
                    *p,
                    format!("{what}: expected 3 numbers, found {}", xs.len()),
                );
            }
            Ok(Vec3::new(
                num(&xs[0], what)?,
                num(&xs[1], what)?,
                num(&xs[2], what)?,
            ))
        }
        other => err(
            other.pos(),
            format!("{what}: expected {{x, y, z}}, found {}", other.describe()),
        ),
    }
}

fn call<'a>(v: &'a Val, what: &str, names: &[&str]) -> Result<&'a Call, ScnError> {
    match v {
        Val::Call(c) if names.contains(&c.name.as_str()) => Ok(c),
        Val::Call(c) => err(
            c.pos,
            format!(
                "{what}: unknown `{}`, expected {}",
                c.name,
                names.join(" or ")
            ),
        ),
        other => err(
            other.pos(),
            format!(
                "{what}: expected {}{{…}}, found {}",
                names.join(" or "),
                other.describe()
            ),
        ),
    }
}

/// Looks up named fields of a constructor, rejecting unknown keys and bare values.
struct Fields<'a> {
    call: &'a Call,
}

impl<'a> Fields<'a> {
    fn new(call: &'a Call, known: &[&str]) -> Result<Self, ScnError> {
        let mut seen: Vec<&str> = Vec::new();
        for it in &call.items {
            match &it.key {
                Some((k, p)) => {
                    if !known.contains(&k.as_str()) {
                        return err(
                            *p,
                            format!(
                                "unknown field `{k}` in `{}`; expected one of {}",
                                call.name,
                                known.join(", ")
                            ),
                        );
                    }
                    if seen.contains(&k.as_str()) {
                        return err(*p, format!("field `{k}` given twice in `{}`", call.name));
                    }
                    seen.push(k);
                }
                None => {
                    return err(
                        it.val.pos(),
                        format!(
                            "`{}` expects `field = value` items, found {}",
                            call.name,
                            it.val.describe()
                        ),
                    )
                }
            }
        }
        Ok(Fields { call })
    }
    fn get(&self, key: &str) -> Option<&'a Val> {
        self.call
            .items
            .iter()
            .find(|it| it.key.as_ref().is_some_and(|(k, _)| k == key))
            .map(|it| &it.val)
    }
    fn num(&self, key: &str, default: f64) -> Result<f64, ScnError> {
        self.get(key)
            .map_or(Ok(default), |v| finite(num(v, key)?, v.pos(), key))
    }
    fn vec3(&self, key: &str, default: Vec3) -> Result<Vec3, ScnError> {
        match self.get(key) {
            None => Ok(default),
            Some(v) => {
                let x = vec3(v, key)?;
                if !x.is_finite() {
                    return err(v.pos(), format!("{key}: not finite"));
                }
                Ok(x)
            }
        }
    }
    fn required(&self, key: &str) -> Result<&'a Val, ScnError> {
        self.get(key).map_or_else(
            || {
                err(
                    self.call.pos,
                    format!("`{}` needs `{key} = …`", self.call.name),
                )
            },
            Ok,
        )
    }
}

fn finite(x: f64, p: Pos, what: &str) -> Result<f64, ScnError> {
    if x.is_finite() {
        Ok(x)
    } else {
        err(p, format!("{what}: not finite"))
    }
}

fn trilist(v: &Val) -> Result<Vec<[Vec3; 3]>, ScnError> {
    let c = call(v, "shape", &["trilist"])?;
    let mut tris = Vec::new();
    for it in &c.items {
        if let Some((k, p)) = &it.key {
            return err(
                *p,
                format!("`trilist` holds triangles {{v0, v1, v2}}, not `{k} = …`"),
            );
        }
        match &it.val {
            Val::List(vs, p) if vs.len() == 3 => {
                let t = [
                    vec3(&vs[0], "vertex")?,
                    vec3(&vs[1], "vertex")?,
                    vec3(&vs[2], "vertex")?,
                ];
                if !t.iter().all(|v| v.is_finite()) {
                    return err(*p, "triangle: not finite");
                }
                tris.push(t);
            }
            other => {
                return err(
                    other.pos(),
                    format!(
                        "expected a triangle {{v0, v1, v2}}, found {}",
                        other.describe()
                    ),
                )
            }
        }
    }
    Ok(tris)
}

fn shape(v: &Val) -> Result<Shape, ScnError> {
    let c = call(v, "shape", &["sphere", "trilist"])?;
    if c.name == "trilist" {
        return Ok(Shape::Triangles {
            triangles: trilist(v)?,
        });
    }
    let f = Fields::new(c, &["center", "radius"])?;
    let radius = f.num("radius", 1.0)?;
    if radius <= 0.0 {
        let p = f.get("radius").map_or(c.pos, Val::pos);
        return err(p, format!("radius must be positive, got {radius}"));
    }
    Ok(Shape::Sphere(Sphere {
        center: f.vec3("center", Vec3::ZERO)?,
        radius,
    }))
}

fn material(v: &Val) -> Result<Brdf, ScnError> {
    let c = call(v, "material", &["plastic"])?;
    let f = Fields::new(c, &["kd", "ks", "kt", "se", "d_col", "s_col", "ka", "ir"])?;
    let kd = f.num("kd", 0.9)?;
    let ks = f.num("ks", 0.0)?;
    let kt = f.num("kt", 0.0)?;
    let se = f.num("se", 10.0)?;
    if kt != 0.0 {
        let p = f.get("kt").map_or(c.pos, Val::pos);
        return err(p, "kt (transmission) is not supported; use kt = 0");
    }
    for (k, x) in [("kd", kd), ("ks", ks)] {
        if x < 0.0 {
            let p = f.get(k).map_or(c.pos, Val::pos);
            return err(p, format!("{k} must be ≥ 0"));
        }
    }
    let d_col = f.vec3("d_col", Vec3::new(1.0, 1.0, 1.0))?;
    let s_col = f.vec3("s_col", Vec3::new(1.0, 1.0, 1.0))?;
    for (k, col) in [("d_col", d_col), ("s_col", s_col)] {
        if col.x < 0.0 || col.y < 0.0 || col.z < 0.0 {
            let p = f.get(k).map_or(c.pos, Val::pos);
            return err(p, format!("{k} must be ≥ 0"));
        }
    }
    let to_rgb = |v: Vec3| Rgb::new(v.x, v.y, v.z);
    Ok(plastic(kd, ks, se, to_rgb(d_col), to_rgb(s_col)))
}

/// The S3D `plastic{kd, ks, se, d_col, s_col}` material as a BRDF (see the module
/// documentation): ρd = kd·d_col, ρs = ks·s_col (both scaled down together where ρd + ρs
/// exceeds 1), normalized Blinn–Phong of exponent `se`; `se < 0` is a perfect mirror of
/// reflectance ks·s_col. Inputs must be non-negative (callers check and report).
pub fn plastic(kd: f64, ks: f64, se: f64, d_col: Rgb, s_col: Rgb) -> Brdf {
    if se < 0.0 {
        let r = s_col * ks;
        let m = r.max_component().max(1.0);
        return Brdf::Mirror(Mirror { reflectance: r / m });
    }
    let (d, s) = (d_col * kd, s_col * ks);
    let m = (d + s).max_component().max(1.0);
    let (d, s) = (d / m, s / m);
    if s.is_black() {
        Brdf::Lambert(Lambert { albedo: d })
    } else {
        Brdf::BlinnPhong(BlinnPhong {
            diffuse: d,
            specular: s,
            exponent: se,
        })
    }
}

fn object(v: &Val, out: &mut Vec<Object>) -> Result<(), ScnError> {
    let c = call(v, "object", &["primobj", "polyobj", "group"])?;
    if c.name == "group" {
        for it in &c.items {
            match &it.key {
                Some((k, _)) if k == "object" => object(&it.val, out)?,
                None => object(&it.val, out)?,
                Some((k, p)) => return err(*p, format!("`group` holds `object = …`, not `{k}`")),
            }
        }
        return Ok(());
    }
    let f = Fields::new(c, &["material", "shape"])?;
    let material = match f.get("material") {
        Some(m) => material(m)?,
        None => Brdf::Lambert(Lambert {
            albedo: Rgb::splat(0.9),
        }),
    };
    let shape = shape(f.required("shape")?)?;
    match (&c.name[..], &shape) {
        ("primobj", Shape::Triangles { .. }) => {
            return err(
                c.pos,
                "`primobj` takes a primitive shape (sphere); use `polyobj` for trilist",
            )
        }
        ("polyobj", Shape::Sphere(_)) => {
            return err(
                c.pos,
                "`polyobj` takes a `trilist`; use `primobj` for a sphere",
            )
        }
        _ => {}
    }
    out.push(Object::new(shape, material));
    Ok(())
}

fn view(v: &Val) -> Result<Camera, ScnError> {
    let c = call(v, "camera", &["view"])?;
    let f = Fields::new(c, &["from", "at", "up", "fov", "imgw", "imgh"])?;
    let size = |k: &str, d: f64| -> Result<usize, ScnError> {
        let x = f.num(k, d)?;
        if x < 1.0 || x.fract() != 0.0 || x > 65536.0 {
            let p = f.get(k).map_or(c.pos, Val::pos);
            return err(
                p,
                format!("{k} must be a positive whole number of pixels, got {x}"),
            );
        }
        Ok(x as usize)
    };
    let (w, h) = (size("imgw", 320.0)?, size("imgh", 240.0)?);
    Camera::look_at(
        f.vec3("from", Vec3::new(0.0, -5.0, 0.0))?,
        f.vec3("at", Vec3::ZERO)?,
        f.vec3("up", Vec3::new(0.0, 0.0, 1.0))?,
        f.num("fov", 90.0)?,
        w,
        h,
    )
    .or_else(|e| err(c.pos, e.to_string()))
}

/// Parses the text of a `.scn` file into a [`Scene`] (book §9.13; see the module docs for the
/// grammar and the mapping of parameters).
pub fn parse_scn(text: &str) -> Result<Scene, ScnError> {
    let toks = lex(text)?;
    let mut p = Parser {
        toks,
        i: 0,
        depth: 0,
    };
    let (name, pos) = match p.next() {
        (Tok::Ident(n), pos) if n == "scene" || n == "hdrscene" => (n, pos),
        (t, pos) => {
            return err(
                pos,
                format!("expected `scene{{` or `hdrscene{{`, found {}", show(&t)),
            )
        }
    };
    let open = p.expect_open(&format!("`{name}`"))?;
    let items = p.items(open)?;
    loop {
        match p.next() {
            (Tok::Semi, _) => {}
            (Tok::Eof, _) => break,
            (t, pos) => return err(pos, format!("unexpected {} after the scene", show(&t))),
        }
    }
    let mut scene = Scene {
        camera: Some(
            Camera::look_at(
                Vec3::new(0.0, -5.0, 0.0),
                Vec3::ZERO,
                Vec3::new(0.0, 0.0, 1.0),
                90.0,
                320,
                240,
            )
            .expect("the default view is valid"),
        ),
        objects: Vec::new(),
        lights: Vec::new(),
        background: Rgb::BLACK,
        dome: None,
    };
    let mut have_camera = false;
    for it in &items {
        let key = it.key.as_ref().map(|(k, _)| k.as_str());
        let cname = match &it.val {
            Val::Call(c) => Some(c.name.as_str()),
            _ => None,
        };
        match (key, cname) {
            (Some("camera"), _) | (None, Some("view")) => {
                if have_camera {
                    return err(it.val.pos(), "a second camera");
                }
                scene.camera = Some(view(&it.val)?);
                have_camera = true;
            }
            (Some("object"), _) | (None, Some("primobj" | "polyobj" | "group")) => {
                object(&it.val, &mut scene.objects)?
            }
            (Some("light"), _) | (None, Some("polylight")) => {
                let c = call(&it.val, "light", &["polylight"])?;
                let f = Fields::new(c, &["color", "shape"])?;
                let color = f.vec3("color", Vec3::new(1.0, 1.0, 1.0))?;
                if color.x < 0.0 || color.y < 0.0 || color.z < 0.0 {
                    return err(f.get("color").map_or(c.pos, Val::pos), "color must be ≥ 0");
                }
                let triangles = trilist(f.required("shape")?)?;
                scene.lights.push(AreaLight {
                    radiance: Rgb::new(color.x, color.y, color.z) * SCN_LIGHT_SCALE,
                    triangles,
                });
            }
            (Some("dome"), _) | (None, Some("hdrdome")) => {
                let c = call(&it.val, "dome", &["hdrdome"])?;
                if name != "hdrscene" {
                    return err(c.pos, "`hdrdome` needs an `hdrscene{…}`");
                }
                let f = Fields::new(c, &["orig", "south", "hdrimg"])?;
                let image = match f.required("hdrimg")? {
                    Val::Str(s, _) => s.clone(),
                    other => {
                        return err(
                            other.pos(),
                            format!(
                                "hdrimg: expected a \"file name\", found {}",
                                other.describe()
                            ),
                        )
                    }
                };
                scene.dome = Some(DomeSpec {
                    orig: f.vec3("orig", Vec3::new(1.0, 0.0, 0.0))?,
                    south: f.vec3("south", Vec3::new(0.0, 0.0, 1.0))?,
                    image,
                    scale: 1.0,
                });
            }
            (Some("shadow"), _) | (None, Some("plshadow")) => {
                let c = call(&it.val, "shadow", &["plshadow"])?;
                let f = Fields::new(c, &["material", "shape"])?;
                let material = match f.get("material") {
                    Some(m) => material(m)?,
                    None => Brdf::Lambert(Lambert {
                        albedo: Rgb::splat(0.9),
                    }),
                };
                let mut o = Object::new(shape(f.required("shape")?)?, material);
                o.catcher = true;
                scene.objects.push(o);
            }
            (Some(k), _) => {
                let p = it.key.as_ref().map(|x| x.1).unwrap_or(pos);
                return err(
                    p,
                    format!(
                        "unknown scene field `{k}`; expected camera, object, light, dome or shadow"
                    ),
                );
            }
            (None, _) => {
                return err(
                    it.val.pos(),
                    format!("unexpected {} in the scene", it.val.describe()),
                )
            }
        }
    }
    Ok(scene)
}

#[cfg(test)]
mod tests;
