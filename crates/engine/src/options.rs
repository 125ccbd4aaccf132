//! Options structs as node parameters: a node type declares the params of an options struct
//! (`#[derive(vfxgraph_params::Options)]`, which lives with its algorithm and knows nothing of
//! the engine) with [`NodeSpec::options`], and its run reads the struct back with
//! [`Context::options`]. Name, type, range, default and doc are written once, on the struct.

use vfxgraph_params::{Options, ParamDesc, Source};

use crate::node::{Context, NodeError, NodeSpec};

/// An options struct a node type declares its params from ([`NodeSpec::options`]): which
/// params are its, and how to read them back, so a test can walk a registry and check every
/// node's declared defaults against its structs without a list of them.
#[derive(Clone, Debug)]
pub struct OptionsDecl {
    /// The struct's Rust type name.
    pub type_name: &'static str,
    /// Its params' names, in declaration order.
    pub params: Vec<&'static str>,
    /// Reads the struct from `src` and describes it again: the params with the values read as
    /// their defaults (for a node's declared defaults, those same defaults).
    pub read_back: fn(&dyn Source) -> Result<Vec<ParamDesc>, String>,
}

fn read_back<T: Options>(src: &dyn Source) -> Result<Vec<ParamDesc>, String> {
    T::read(src).map(|t| T::params_from(&t))
}

impl NodeSpec {
    /// Adds the params of options struct `T`, in its field order.
    pub fn options<T: Options>(self) -> Self {
        self.declare::<T>(T::params())
    }

    /// Adds the params of options struct `T` with the values of `defaults` as their defaults
    /// (a node type whose defaults differ from `T`'s `Default`, as an OpenCV cross-check
    /// without drift correction).
    pub fn options_from<T: Options>(self, defaults: &T) -> Self {
        self.declare::<T>(T::params_from(defaults))
    }

    fn declare<T: Options>(mut self, params: Vec<ParamDesc>) -> Self {
        self.options.push(OptionsDecl {
            type_name: std::any::type_name::<T>(),
            params: params.iter().map(|d| d.name).collect(),
            read_back: read_back::<T>,
        });
        for d in params {
            self = self.param(d);
        }
        self
    }
}

impl Context<'_> {
    /// Reads options struct `T` from the node's params (checked by `T`'s `check`).
    pub fn options<T: Options>(&self) -> Result<T, NodeError> {
        T::read(self.params()).map_err(NodeError::msg)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::param::{Kind, ParamValue, Params, PathRole};
    use std::collections::BTreeMap;
    use vfxgraph_params::Choice;

    #[derive(Clone, Copy, Debug, PartialEq, Choice)]
    enum Loss {
        None,
        SoftL1,
    }

    /// The test's options.
    #[derive(Debug, PartialEq, Options)]
    #[param(check)]
    struct Opts {
        /// how many
        ///
        /// (not in the param doc)
        #[param(range = 1..=10)]
        count: usize,
        /// a scale
        #[param(range = 0.5..=, name = "scale_factor")]
        scale: f64,
        /// the loss
        loss: Loss,
        #[param(skip)]
        seed: u64,
        /// refine
        #[param(toggle = "refine")]
        inner: Option<Inner>,
    }

    impl Default for Opts {
        fn default() -> Self {
            Opts {
                count: 3,
                scale: 1.5,
                loss: Loss::SoftL1,
                seed: 7,
                inner: Some(Inner::default()),
            }
        }
    }

    impl Opts {
        fn check(&self) -> Result<(), String> {
            if self.count == 4 {
                return Err("`count` must not be 4".into());
            }
            Ok(())
        }
    }

    #[derive(Debug, PartialEq, Options)]
    struct Inner {
        /// the values
        values: Vec<f64>,
    }

    impl Default for Inner {
        fn default() -> Self {
            Inner { values: vec![1.0] }
        }
    }

    #[test]
    fn an_options_struct_is_a_node_spec_and_reads_back() {
        let spec = NodeSpec::new("t", "test").options::<Opts>();
        let names: Vec<&str> = spec.params.iter().map(|p| p.name).collect();
        assert_eq!(names, ["count", "scale_factor", "loss", "refine", "values"]);
        let p = &spec.params[0];
        assert_eq!(p.kind, Kind::Int { min: 1, max: 10 });
        assert_eq!(p.default, Some(ParamValue::Int(3)));
        assert_eq!(p.doc, "how many");
        assert_eq!(
            spec.params[1].kind,
            Kind::Float {
                min: 0.5,
                max: f64::INFINITY
            }
        );
        assert_eq!(spec.params[2].kind, Kind::Enum(&["none", "soft_l1"]));
        assert_eq!(
            spec.params[2].default,
            Some(ParamValue::Str("soft_l1".into()))
        );
        assert_eq!(spec.params[3].default, Some(ParamValue::Bool(true)));

        let mut values: BTreeMap<String, ParamValue> = spec
            .params
            .iter()
            .map(|p| (p.name.to_string(), p.default.clone().unwrap()))
            .collect();
        let params = Params::new(values.clone());
        assert_eq!(Opts::read(&params).unwrap(), Opts::default());
        values.insert("refine".into(), ParamValue::Bool(false));
        values.insert("loss".into(), ParamValue::Str("none".into()));
        values.insert("count".into(), ParamValue::Int(4));
        let e = Opts::read(&Params::new(values.clone())).unwrap_err();
        assert_eq!(e, "`count` must not be 4");
        values.insert("count".into(), ParamValue::Int(5));
        let o = Opts::read(&Params::new(values)).unwrap();
        assert_eq!((o.count, o.loss, o.seed, o.inner), (5, Loss::None, 7, None));
        assert_eq!(Loss::from_choice("none"), Some(Loss::None));
    }

    /// Paths and optional indices.
    #[derive(Debug, Default, PartialEq, Options)]
    struct Files {
        /// the plate
        #[param(path = "input")]
        plate: String,
        /// the reference; -1 = none
        #[param(range = -1..=100)]
        reference: Option<usize>,
    }

    #[test]
    fn a_path_field_is_a_path_param_and_minus_one_is_none() {
        let spec = NodeSpec::new("t", "test").options::<Files>();
        assert_eq!(spec.params[0].kind, Kind::Path(PathRole::Input));
        assert_eq!(spec.params[0].default, Some(ParamValue::Str(String::new())));
        assert_eq!(spec.params[1].kind, Kind::Int { min: -1, max: 100 });
        assert_eq!(spec.params[1].default, Some(ParamValue::Int(-1)));
        let mut values = BTreeMap::new();
        values.insert("plate".to_string(), ParamValue::Str("a.exr".into()));
        values.insert("reference".to_string(), ParamValue::Int(3));
        let read = Files::read(&Params::new(values)).unwrap();
        assert_eq!((read.plate.as_str(), read.reference), ("a.exr", Some(3)));
    }

    /// A flattened struct whose defaults the outer struct sets, and floats whose 0 is off.
    #[derive(Debug, PartialEq, Options)]
    struct Outer {
        #[param(flatten)]
        inner: Thresholds,
    }

    #[derive(Debug, Default, PartialEq, Options)]
    struct Thresholds {
        /// a threshold; 0 = off
        check: Option<f32>,
        /// a tolerance
        tolerance: f32,
    }

    impl Default for Outer {
        fn default() -> Self {
            Outer {
                inner: Thresholds {
                    check: Some(2.5),
                    tolerance: 1e-5,
                },
            }
        }
    }

    #[test]
    fn flattened_defaults_are_the_outer_structs_and_zero_is_off() {
        let spec = NodeSpec::new("t", "test").options::<Outer>();
        assert_eq!(spec.params[0].default, Some(ParamValue::Float(2.5)));
        // An f32 default is its shortest decimal, not its binary value.
        assert_eq!(spec.params[1].default, Some(ParamValue::Float(1e-5)));
        let spec = NodeSpec::new("t", "test").options_from(&Outer {
            inner: Thresholds::default(),
        });
        assert_eq!(spec.params[0].default, Some(ParamValue::Float(0.0)));
        let mut values = BTreeMap::new();
        values.insert("check".to_string(), ParamValue::Float(0.0));
        values.insert("tolerance".to_string(), ParamValue::Float(1e-5));
        let read = Outer::read(&Params::new(values.clone())).unwrap();
        assert_eq!(read.inner.check, None);
        assert_eq!(read.inner.tolerance, 1e-5_f32);
        values.insert("check".to_string(), ParamValue::Float(2.5));
        assert_eq!(Outer::read(&Params::new(values)).unwrap(), Outer::default());
    }

    /// A required param and a path list, beside a flattened struct.
    #[derive(Debug, Default, PartialEq, Options)]
    struct Node {
        /// the frame
        #[param(required)]
        frame: i64,
        /// the photographs
        #[param(path = "input")]
        photos: Vec<String>,
        #[param(flatten)]
        files: Files,
    }

    #[test]
    fn a_required_param_has_no_default_and_is_recorded_with_its_struct() {
        let spec = NodeSpec::new("t", "test").options::<Node>();
        assert_eq!(spec.params[0].default, None);
        assert_eq!(
            spec.params[0].kind,
            Kind::Int {
                min: i64::MIN,
                max: i64::MAX
            }
        );
        assert_eq!(spec.params[1].kind, Kind::PathList(PathRole::Input));
        assert_eq!(spec.params[1].default, Some(ParamValue::List(vec![])));
        let decl = &spec.options[0];
        assert_eq!(decl.params, ["frame", "photos", "plate", "reference"]);
        let mut values = BTreeMap::new();
        values.insert("photos".to_string(), ParamValue::List(vec![]));
        values.insert("plate".to_string(), ParamValue::Str(String::new()));
        values.insert("reference".to_string(), ParamValue::Int(-1));
        let e = Node::read(&Params::new(values.clone())).unwrap_err();
        assert_eq!(e, "parameter `frame` has no value");
        values.insert("frame".to_string(), ParamValue::Int(12));
        let photos = ParamValue::List(vec![ParamValue::Str("a.jpg".into())]);
        values.insert("photos".to_string(), photos);
        let read = Node::read(&Params::new(values.clone())).unwrap();
        assert_eq!(
            (read.frame, read.photos.as_slice()),
            (12, &["a.jpg".to_string()][..])
        );
        let again = (decl.read_back)(&Params::new(values)).unwrap();
        assert_eq!(again[0].default, None);
        assert_eq!(again[3].default, Some(ParamValue::Int(-1)));
    }
}
