//! openapi.yaml's enums and problem list against the code's tables: every closed set a client
//! names (methods, fills, mesh formats, CSG and morphology operations, kernels) is listed in the
//! contract exactly as its [`Named`] table lists it, and the Problem schema lists every error kind
//! with its status, in the order of the one table of kinds (`app/error.rs`). A set that grows in
//! the code but not in the contract (or the reverse) fails here.
//!
//! Not here: whether real responses match the schemas (`tests/service/contract.rs`), the route table.

use std::collections::BTreeMap;
use std::path::Path;

use serde_json::Value;
use voxd::app::ErrorKind;
use voxd::app::request::MethodName;
use voxd::codec::format::VolumeFormat;
use voxd::engine::fill::Fill;
use voxd::mesh::Format;
use voxd::names::Named;
use voxd::volume::csg::CsgOp;
use voxd::volume::morph::{Kernel, MorphOp};

fn document() -> Value {
    let yaml = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("openapi.yaml"))
        .expect("openapi.yaml is readable");
    serde_norway::from_str(&yaml).expect("openapi.yaml parses")
}

/// Every string enum of the document, by (route or schema name, parameter or property name).
/// A key that occurs more than once in one place keeps every list.
fn enums(doc: &Value) -> BTreeMap<(String, String), Vec<Vec<String>>> {
    fn strings(v: &Value) -> Option<Vec<String>> {
        v.get("enum")?
            .as_array()?
            .iter()
            .map(|s| s.as_str().map(str::to_string))
            .collect()
    }
    fn walk(v: &Value, place: &str, out: &mut BTreeMap<(String, String), Vec<Vec<String>>>) {
        match v {
            Value::Object(m) => {
                if let (Some(name), Some(list)) = (
                    m.get("name").and_then(Value::as_str),
                    m.get("schema").and_then(strings),
                ) {
                    out.entry((place.into(), name.into()))
                        .or_default()
                        .push(list);
                }
                if let Some(Value::Object(props)) = m.get("properties") {
                    for (name, p) in props {
                        if let Some(list) = strings(p) {
                            out.entry((place.into(), name.clone()))
                                .or_default()
                                .push(list);
                        }
                    }
                }
                m.values().for_each(|c| walk(c, place, out));
            }
            Value::Array(a) => a.iter().for_each(|c| walk(c, place, out)),
            _ => {}
        }
    }
    let mut out = BTreeMap::new();
    for section in ["/paths", "/components/schemas"] {
        let places = doc.pointer(section).and_then(Value::as_object);
        for (place, v) in places.expect("the document has paths and schemas") {
            walk(v, place, &mut out);
        }
    }
    out
}

fn names<T: Named>() -> Vec<String> {
    T::ALL.iter().map(|v| v.name().to_string()).collect()
}

fn sorted(mut v: Vec<String>) -> Vec<String> {
    v.sort();
    v
}

/// The one list at (place, key); fails when there is none or more than one.
fn one<'a>(
    all: &'a BTreeMap<(String, String), Vec<Vec<String>>>,
    place: &str,
    key: &str,
) -> &'a [String] {
    match all
        .get(&(place.to_string(), key.to_string()))
        .map(Vec::as_slice)
    {
        Some([list]) => list,
        other => panic!("openapi.yaml: expected one enum {key} at {place}, found {other:?}"),
    }
}

#[test]
fn named_sets_match_the_contract() {
    let all = enums(&document());
    let voxelize = "/v1/voxelize";
    assert_eq!(one(&all, voxelize, "method"), names::<MethodName>());
    assert_eq!(one(&all, voxelize, "fill"), names::<Fill>());
    // The contract lists glb before gltf; the set is what matters.
    assert_eq!(
        sorted(one(&all, voxelize, "format").to_vec()),
        sorted(names::<Format>())
    );
    assert_eq!(
        one(&all, "/v1/volumes/{id}/data", "format"),
        names::<VolumeFormat>()
    );
    let morphology = "/v1/volumes/{id}/morphology";
    assert_eq!(one(&all, morphology, "op"), names::<MorphOp>());
    assert_eq!(one(&all, morphology, "kernel"), names::<Kernel>());

    // Every other `op` is a CSG operation, and there is at least one.
    let csg: Vec<_> = all
        .iter()
        .filter(|((place, key), _)| key == "op" && place != morphology)
        .flat_map(|(_, lists)| lists)
        .collect();
    assert!(!csg.is_empty(), "openapi.yaml lists no CSG op");
    for list in csg {
        assert_eq!(*list, names::<CsgOp>());
    }

    // A volume's fill report: the fill asked for, and the one used (auto resolved).
    let fills: Vec<_> = all
        .iter()
        .filter(|((_, key), _)| key == "requested" || key == "used")
        .collect();
    assert_eq!(fills.len(), 2, "{fills:?}");
    for ((_, key), lists) in fills {
        let mut want = names::<Fill>();
        if key == "used" {
            want.retain(|f| f != Fill::Auto.name());
        }
        assert_eq!(lists, &[want]);
    }
}

/// The Problem schema's description lists `code (status)` for every kind, in the table's order.
#[test]
fn every_error_kind_is_documented_with_its_status() {
    let doc = document();
    let text = doc
        .pointer("/components/schemas/Problem/description")
        .and_then(Value::as_str)
        .expect("the Problem schema has a description");
    let list = text
        .split_once("https://voxd.dev/problems/")
        .expect("the description names the problem type base")
        .1;
    let documented: Vec<(String, u16)> = list
        .trim()
        .trim_end_matches('.')
        .split(',')
        .map(|item| {
            let (code, status) = item
                .trim()
                .split_once(" (")
                .unwrap_or_else(|| panic!("expected `code (status)`, got {item:?}"));
            let status = status.trim_end_matches(')').parse().expect("a status");
            (code.to_string(), status)
        })
        .collect();
    let table: Vec<(String, u16)> = ErrorKind::ALL
        .iter()
        .map(|k| (k.code().to_string(), k.status()))
        .collect();
    assert_eq!(documented, table);
}
