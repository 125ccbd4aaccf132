//! The derives of `vfxgraph-params` (see that crate for the attributes): `Options` on a struct
//! with named fields, `Choice` on a unit-only enum. The generated code names only
//! `::vfxgraph_params`, never the engine.

use proc_macro::TokenStream;
use proc_macro2::TokenStream as Tokens;
use quote::quote;
use syn::parse::ParseStream;
use syn::{parse_macro_input, Attribute, Data, DeriveInput, Fields, LitStr, Token, Type};

/// Derives `vfxgraph_params::Options` (params from fields, defaults from `Default`).
#[proc_macro_derive(Options, attributes(param))]
pub fn derive_options(input: TokenStream) -> TokenStream {
    let input = parse_macro_input!(input as DeriveInput);
    options(&input)
        .unwrap_or_else(syn::Error::into_compile_error)
        .into()
}

/// Derives `vfxgraph_params::Choice` and `Field` (variants in snake case, or `#[param(name)]`).
#[proc_macro_derive(Choice, attributes(param))]
pub fn derive_choice(input: TokenStream) -> TokenStream {
    let input = parse_macro_input!(input as DeriveInput);
    choice(&input)
        .unwrap_or_else(syn::Error::into_compile_error)
        .into()
}

/// What `#[param(...)]` says about one field (or variant).
#[derive(Default)]
struct FieldAttrs {
    name: Option<LitStr>,
    doc: Option<LitStr>,
    min: Option<Tokens>,
    max: Option<Tokens>,
    skip: bool,
    flatten: bool,
    toggle: Option<LitStr>,
    path: Option<LitStr>,
    cosmetic: bool,
    required: bool,
    check: bool,
}

/// Tokens up to the next `,` (or the end), or up to `..=` when `range_start`.
fn tokens_until(input: ParseStream, range_start: bool) -> syn::Result<Option<Tokens>> {
    let mut out = Tokens::new();
    let at_end = |input: ParseStream| {
        input.is_empty() || input.peek(Token![,]) || (range_start && input.peek(Token![..=]))
    };
    while !at_end(input) {
        let tt: proc_macro2::TokenTree = input.parse()?;
        out.extend(std::iter::once(tt));
    }
    Ok((!out.is_empty()).then_some(out))
}

fn field_attrs(attrs: &[Attribute]) -> syn::Result<FieldAttrs> {
    let mut a = FieldAttrs::default();
    for attr in attrs.iter().filter(|a| a.path().is_ident("param")) {
        attr.parse_nested_meta(|meta| {
            let p = &meta.path;
            if p.is_ident("name") {
                a.name = Some(meta.value()?.parse()?);
            } else if p.is_ident("doc") {
                a.doc = Some(meta.value()?.parse()?);
            } else if p.is_ident("toggle") {
                a.toggle = Some(meta.value()?.parse()?);
            } else if p.is_ident("path") {
                let role: LitStr = meta.value()?.parse()?;
                if !matches!(role.value().as_str(), "input" | "output") {
                    return Err(meta.error("path = \"input\" or \"output\""));
                }
                a.path = Some(role);
            } else if p.is_ident("range") {
                let v = meta.value()?;
                a.min = tokens_until(v, true)?;
                v.parse::<Token![..=]>()?;
                a.max = tokens_until(v, false)?;
            } else if p.is_ident("skip") {
                a.skip = true;
            } else if p.is_ident("flatten") {
                a.flatten = true;
            } else if p.is_ident("cosmetic") {
                a.cosmetic = true;
            } else if p.is_ident("required") {
                a.required = true;
            } else if p.is_ident("check") {
                a.check = true;
            } else {
                return Err(meta.error("unknown param attribute"));
            }
            Ok(())
        })?;
    }
    Ok(a)
}

/// The first paragraph of the doc comment, lines joined by spaces.
fn doc_comment(attrs: &[Attribute]) -> String {
    let mut lines = Vec::new();
    for attr in attrs.iter().filter(|a| a.path().is_ident("doc")) {
        if let syn::Meta::NameValue(nv) = &attr.meta {
            if let syn::Expr::Lit(syn::ExprLit {
                lit: syn::Lit::Str(s),
                ..
            }) = &nv.value
            {
                let line = s.value().trim().to_string();
                if line.is_empty() {
                    if !lines.is_empty() {
                        break;
                    }
                } else {
                    lines.push(line);
                }
            }
        }
    }
    lines.join(" ")
}

/// `T` of `Option<T>`.
fn option_inner(ty: &Type) -> Option<&Type> {
    let Type::Path(tp) = ty else { return None };
    let seg = tp.path.segments.last()?;
    if seg.ident != "Option" {
        return None;
    }
    let syn::PathArguments::AngleBracketed(args) = &seg.arguments else {
        return None;
    };
    match args.args.first()? {
        syn::GenericArgument::Type(t) => Some(t),
        _ => None,
    }
}

/// Whether `ty` is a `Vec<_>` (a path list, with `path = ...`).
fn is_vec(ty: &Type) -> bool {
    let Type::Path(tp) = ty else { return false };
    tp.path.segments.last().is_some_and(|s| s.ident == "Vec")
}

fn bound(t: &Option<Tokens>) -> Tokens {
    match t {
        Some(t) => quote!(::core::option::Option::Some((#t) as f64)),
        None => quote!(::core::option::Option::None),
    }
}

fn options(input: &DeriveInput) -> syn::Result<Tokens> {
    let ident = &input.ident;
    let Data::Struct(data) = &input.data else {
        return Err(syn::Error::new_spanned(ident, "Options needs a struct"));
    };
    let Fields::Named(fields) = &data.fields else {
        return Err(syn::Error::new_spanned(ident, "Options needs named fields"));
    };
    let top = field_attrs(&input.attrs)?;
    let mut descs = Vec::new();
    let mut toggled = Vec::new();
    let mut reads = Vec::new();
    for f in &fields.named {
        let field = f.ident.as_ref().expect("named");
        let ty = &f.ty;
        let a = field_attrs(&f.attrs)?;
        let name = a
            .name
            .clone()
            .unwrap_or_else(|| LitStr::new(&field.to_string(), field.span()));
        let doc = a
            .doc
            .clone()
            .unwrap_or_else(|| LitStr::new(&doc_comment(&f.attrs), field.span()));
        let cosmetic = a.cosmetic;
        if a.required && (a.skip || a.flatten || a.toggle.is_some()) {
            return Err(syn::Error::new_spanned(
                field,
                "required is for a parameter field, not with skip, flatten or toggle",
            ));
        }
        if a.skip {
            reads.push(quote!(#field: d.#field));
        } else if a.flatten {
            descs.push(
                quote!(out.extend(<#ty as ::vfxgraph_params::Options>::params_from(&d.#field));),
            );
            reads.push(quote!(#field: <#ty as ::vfxgraph_params::Options>::read(src)?));
        } else if let Some(toggle) = &a.toggle {
            let inner = option_inner(ty)
                .ok_or_else(|| syn::Error::new_spanned(ty, "toggle needs an Option<T> field"))?;
            descs.push(quote!(out.push(::vfxgraph_params::ParamDesc {
                name: #toggle,
                kind: ::vfxgraph_params::Kind::Bool,
                default: ::core::option::Option::Some(::vfxgraph_params::Value::Bool(d.#field.is_some())),
                doc: #doc,
                cosmetic: #cosmetic,
            });));
            toggled.push(quote!(out.extend(<#inner as ::vfxgraph_params::Options>::params());));
            reads.push(
                quote!(#field: if ::vfxgraph_params::read_field::<bool>(src, #toggle)? {
                    ::core::option::Option::Some(<#inner as ::vfxgraph_params::Options>::read(src)?)
                } else {
                    ::core::option::Option::None
                }),
            );
        } else {
            let (min, max) = (bound(&a.min), bound(&a.max));
            let path = if is_vec(ty) {
                quote!(PathList)
            } else {
                quote!(Path)
            };
            let kind = match a.path.as_ref().map(LitStr::value).as_deref() {
                Some("input") => quote!(::vfxgraph_params::Kind::#path(
                    ::vfxgraph_params::PathRole::Input
                )),
                Some(_) => quote!(::vfxgraph_params::Kind::#path(
                    ::vfxgraph_params::PathRole::Output
                )),
                None => quote!(<#ty as ::vfxgraph_params::Field>::kind(#min, #max)),
            };
            let default = if a.required {
                quote!(::core::option::Option::None)
            } else {
                quote!(::core::option::Option::Some(::vfxgraph_params::Field::to_value(&d.#field)))
            };
            descs.push(quote!(out.push(::vfxgraph_params::ParamDesc {
                name: #name,
                kind: #kind,
                default: #default,
                doc: #doc,
                cosmetic: #cosmetic,
            });));
            reads.push(quote!(#field: ::vfxgraph_params::read_field::<#ty>(src, #name)?));
        }
    }
    let check = top.check.then(|| quote!(out.check()?;));
    let (imp, tyg, wh) = input.generics.split_for_impl();
    Ok(quote! {
        impl #imp ::vfxgraph_params::Options for #ident #tyg #wh {
            fn params() -> ::std::vec::Vec<::vfxgraph_params::ParamDesc> {
                <Self as ::vfxgraph_params::Options>::params_from(
                    &<Self as ::core::default::Default>::default(),
                )
            }
            fn params_from(d: &Self) -> ::std::vec::Vec<::vfxgraph_params::ParamDesc> {
                let _ = d;
                let mut out = ::std::vec::Vec::new();
                #(#descs)*
                #(#toggled)*
                out
            }
            fn read(src: &dyn ::vfxgraph_params::Source) -> ::core::result::Result<Self, ::std::string::String> {
                #[allow(unused_variables)]
                let d = <Self as ::core::default::Default>::default();
                let out = #ident { #(#reads),* };
                #check
                ::core::result::Result::Ok(out)
            }
        }
    })
}

/// `CamelCase` → `camel_case`.
fn snake(s: &str) -> String {
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if c.is_uppercase() {
            if i > 0 {
                out.push('_');
            }
            out.extend(c.to_lowercase());
        } else {
            out.push(c);
        }
    }
    out
}

fn choice(input: &DeriveInput) -> syn::Result<Tokens> {
    let ident = &input.ident;
    let Data::Enum(data) = &input.data else {
        return Err(syn::Error::new_spanned(ident, "Choice needs an enum"));
    };
    let mut names = Vec::new();
    let mut variants = Vec::new();
    for v in &data.variants {
        if !matches!(v.fields, Fields::Unit) {
            return Err(syn::Error::new_spanned(v, "Choice needs unit variants"));
        }
        let a = field_attrs(&v.attrs)?;
        let name = a
            .name
            .map(|n| n.value())
            .unwrap_or_else(|| snake(&v.ident.to_string()));
        names.push(name);
        variants.push(v.ident.clone());
    }
    Ok(quote! {
        impl ::vfxgraph_params::Choice for #ident {
            const CHOICES: &'static [&'static str] = &[#(#names),*];
            fn choice(&self) -> &'static str {
                match self { #(#ident::#variants => #names),* }
            }
            fn from_choice(name: &str) -> ::core::option::Option<Self> {
                match name {
                    #(#names => ::core::option::Option::Some(#ident::#variants),)*
                    _ => ::core::option::Option::None,
                }
            }
        }
        impl ::vfxgraph_params::Field for #ident {
            fn kind(_: ::core::option::Option<f64>, _: ::core::option::Option<f64>) -> ::vfxgraph_params::Kind {
                ::vfxgraph_params::Kind::Enum(<#ident as ::vfxgraph_params::Choice>::CHOICES)
            }
            fn to_value(&self) -> ::vfxgraph_params::Value {
                ::vfxgraph_params::Value::Str(::vfxgraph_params::Choice::choice(self).to_string())
            }
            fn from_value(v: ::vfxgraph_params::Value) -> ::core::option::Option<Self> {
                ::vfxgraph_params::choice_from_value(v)
            }
        }
    })
}
