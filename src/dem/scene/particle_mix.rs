//! The grains of a generated scene named in its `[source]`: `particle = "name"` makes every
//! grain a clump of one shape, `particles = [{ clump = "a", fraction = 0.3 }, …]` a mixture.
//! A name is a `[[clump]]` table's (its `name`, else its `shape`: `rod 3` for a rod of three) or
//! a built-in shape's where no table has it (`dimer`, `trimer`, `tetrahedron`, `rod`). Before
//! the scene is read, the two keys become the `[[clump]]` tables themselves (`dem::clump_spec`):
//! the tables named, in the mixture's order with its fractions, and no other; so a scene is
//! written in one form.
//!
//! ```toml
//! [source]
//! scene = "pour"
//! particles = [{ clump = "bean", fraction = 0.3 }, { clump = "tetrahedron", fraction = 0.7 }]
//!
//! [[clump]]
//! name = "bean"
//! spheres = [[0, 0, 0, 1], [1.2, 0, 0, 0.8]]
//! ```

use crate::dem::clump_spec::SHAPES;
use crate::error::{Error, Result};
use toml::{Table, Value};

/// `scene` (in the full form) with its `[source]`'s `particle` or `particles` made its
/// `[[clump]]` tables, as the module says; unchanged where it names neither.
pub fn into_clump_tables(mut scene: Table) -> Result<Table> {
    let Some(Value::Table(source)) = scene.get_mut("source") else {
        return Ok(scene);
    };
    let (particle, particles) = (source.remove("particle"), source.remove("particles"));
    let kind = source
        .get("scene")
        .and_then(Value::as_str)
        .unwrap_or("pour");
    let mix = match (particle, particles) {
        (None, None) => return Ok(scene),
        (Some(_), Some(_)) => {
            return Err(refused(
                "particle",
                "names one grain, particles a mixture: give one".into(),
            ));
        }
        _ if kind == "input" => {
            return Err(refused(
                "particles",
                "is for generated grains: scene \"input\" takes its clumps' templates from \
                 its file's rows"
                    .into(),
            ));
        }
        (Some(Value::String(name)), None) => vec![(name, 1.0)],
        (Some(other), None) => {
            return Err(refused(
                "particle",
                format!("must be the name of a [[clump]] table or a built-in shape, got {other}"),
            ));
        }
        (None, Some(Value::Array(entries))) => entries
            .iter()
            .map(mixture_entry)
            .collect::<Result<Vec<_>>>()?,
        (None, Some(other)) => {
            return Err(refused(
                "particles",
                format!("must be a list of {{ clump = \"name\", fraction = w }}, got {other}"),
            ));
        }
    };
    let tables = match scene.remove("clump") {
        None => Vec::new(),
        Some(Value::Array(tables)) => tables,
        Some(other) => vec![other],
    };
    let mut chosen: Vec<Value> = Vec::with_capacity(mix.len());
    for (k, (name, fraction)) in mix.iter().enumerate() {
        if mix[..k].iter().any(|(earlier, _)| earlier == name) {
            return Err(refused("particles", format!("names \"{name}\" twice")));
        }
        let mut table = match tables
            .iter()
            .find(|t| table_name(t).as_deref() == Some(name))
        {
            Some(Value::Table(t)) if t.contains_key("fraction") => {
                return Err(refused(
                    "particles",
                    format!(
                        "gives \"{name}\" a fraction, and so does its [[clump]] table: give it \
                         in one place"
                    ),
                ));
            }
            Some(Value::Table(t)) => t.clone(),
            _ if SHAPES.split(", ").any(|shape| shape == name) => {
                Table::from_iter([("shape".to_owned(), Value::String(name.clone()))])
            }
            _ => {
                let names: Vec<String> = tables
                    .iter()
                    .filter_map(table_name)
                    .map(|n| format!("\"{n}\""))
                    .collect();
                let given = match names.is_empty() {
                    true => "the scene has no [[clump]] tables".to_owned(),
                    false => format!("not one of the [[clump]] tables ({})", names.join(", ")),
                };
                return Err(refused(
                    "particles",
                    format!("names \"{name}\": {given}, nor a built-in shape ({SHAPES})"),
                ));
            }
        };
        table.insert("fraction".into(), Value::Float(*fraction));
        chosen.push(Value::Table(table));
    }
    scene.insert("clump".into(), Value::Array(chosen));
    Ok(scene)
}

/// The name of a `[[clump]]` table as a mixture names it: its `name`, else its `shape` (with
/// a rod's `count`: `rod 3`).
fn table_name(table: &Value) -> Option<String> {
    let table = table.as_table()?;
    if let Some(name) = table.get("name").and_then(Value::as_str) {
        return Some(name.to_owned());
    }
    let shape = table.get("shape").and_then(Value::as_str)?;
    match (shape, table.get("count").and_then(Value::as_integer)) {
        ("rod", Some(count)) => Some(format!("rod {count}")),
        _ => Some(shape.to_owned()),
    }
}

/// One entry `{ clump = "name", fraction = w }` of `particles` (fraction default 1).
fn mixture_entry(entry: &Value) -> Result<(String, f64)> {
    let bad = || {
        refused(
            "particles",
            format!("takes entries {{ clump = \"name\", fraction = w }}, got {entry}"),
        )
    };
    let table = entry.as_table().ok_or_else(bad)?;
    if table.keys().any(|k| k != "clump" && k != "fraction") {
        return Err(bad());
    }
    let name = table.get("clump").and_then(Value::as_str).ok_or_else(bad)?;
    let fraction = match table.get("fraction") {
        None => 1.0,
        Some(Value::Float(w)) => *w,
        Some(Value::Integer(w)) => *w as f64,
        Some(_) => return Err(bad()),
    };
    Ok((name.to_owned(), fraction))
}

/// The error of `[source]`'s key `key`.
fn refused(key: &str, reason: String) -> Error {
    Error::InvalidConfig {
        what: format!("scene key source.{key}"),
        reason,
    }
}
