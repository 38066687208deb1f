//! The short forms of a scene's keys. A scene's fields live in its tables (`[run]`, `[source]`,
//! `[domain]`, `[material]`) and lists of tables; a flat key such as `friction = 0.3` or
//! `spheres = 4000` stands for one of them (`material.friction`, `source.spheres`), and
//! `[[material]]` and `[[material_pair]]` for `[[materials]]` and `[[material_pairs]]`. Scene
//! files, `--set` and Python's dicts may use either form; a scene is written in the full one.

use crate::error::{Error, Result};

/// Each short form, with the table and the key of that table it stands for.
pub const SHORT_FORMS: [(&str, &str, &str); 52] = [
    ("scene", "source", "scene"),
    ("spheres", "source", "spheres"),
    ("particle", "source", "particle"),
    ("particles", "source", "particles"),
    ("seed", "source", "seed"),
    ("input", "source", "input"),
    ("mesh", "source", "mesh"),
    ("mesh_radius", "source", "radius"),
    ("mesh_mixed", "source", "mixed"),
    ("mesh_size", "source", "size"),
    ("mesh_copies", "source", "copies"),
    ("grain_radius", "source", "grain_radius"),
    ("hopper_orifice", "source", "orifice"),
    ("hopper_angle", "source", "angle"),
    ("hopper_open", "source", "open"),
    ("drum_omega", "source", "omega"),
    ("drum_sides", "source", "sides"),
    ("drum_rings", "source", "rings"),
    ("agglomerate_speed", "source", "speed"),
    ("steps", "run", "steps"),
    ("dt", "run", "dt"),
    ("mode", "run", "mode"),
    ("frame_every", "run", "frame_every"),
    ("csv", "run", "csv"),
    ("frame_pieces", "run", "frame_pieces"),
    ("checkpoint_pieces", "run", "checkpoint_pieces"),
    ("flow_every", "run", "flow_every"),
    ("box_lo", "domain", "box_lo"),
    ("box_hi", "domain", "box_hi"),
    ("gravity", "domain", "gravity"),
    ("gravity_spin", "domain", "gravity_spin"),
    ("box_walls", "domain", "box_walls"),
    ("box_material", "domain", "box_material"),
    ("contact", "material", "contact"),
    ("density", "material", "density"),
    ("restitution", "material", "restitution"),
    ("stiffness", "material", "stiffness"),
    ("contact_time", "material", "contact_time"),
    ("young_modulus", "material", "young_modulus"),
    ("poisson_ratio", "material", "poisson_ratio"),
    ("friction", "material", "friction"),
    ("wall_friction", "material", "wall_friction"),
    ("rolling_friction", "material", "rolling_friction"),
    ("rolling_model", "material", "rolling_model"),
    ("tangential_model", "material", "tangential_model"),
    ("cohesion", "material", "cohesion"),
    ("surface_energy", "material", "surface_energy"),
    ("liquid_volume", "material", "liquid_volume"),
    ("surface_tension", "material", "surface_tension"),
    ("contact_angle", "material", "contact_angle"),
    ("liquid_viscosity", "material", "liquid_viscosity"),
    (
        "cohesion_energy_density",
        "material",
        "cohesion_energy_density",
    ),
];

/// The tables a scene's fields live in.
const TABLES: [&str; 4] = ["run", "source", "domain", "material"];

/// The keys a scene file holds at its top (`SceneConfig`'s fields), once short forms are
/// expanded.
const TOP_LEVEL: [&str; 10] = [
    "run",
    "source",
    "domain",
    "material",
    "materials",
    "material_pairs",
    "wall",
    "inflow",
    "outflow",
    "clump",
];

/// Lists of tables by their short and full names. `material` is the `[material]` table too:
/// it stands for `materials` only as a list (or indexed, `material.0.friction`).
const LISTS: [(&str, &str); 2] = [
    ("material", "materials"),
    ("material_pair", "material_pairs"),
];

/// The table and key the short form `key` stands for.
fn expand(key: &str) -> Option<(&'static str, &'static str)> {
    SHORT_FORMS
        .iter()
        .find(|(short, _, _)| *short == key)
        .map(|&(_, table, full)| (table, full))
}

/// The short form of `key` of `table`, if it has one.
pub fn short_form(table: &str, key: &str) -> Option<&'static str> {
    SHORT_FORMS
        .iter()
        .find(|(_, t, k)| *t == table && *k == key)
        .map(|&(short, _, _)| short)
}

/// The full path of `path` (a key, or a dotted path into a table or a list of tables by
/// index) whose value is `value`.
pub fn full_path(path: &[String], value: &toml::Value) -> Vec<String> {
    let (first, rest) = path.split_first().expect("a path has a key");
    if let Some((table, key)) = expand(first) {
        return [table, key]
            .into_iter()
            .map(str::to_owned)
            .chain(rest.iter().cloned())
            .collect();
    }
    let listed = match rest.first() {
        Some(next) => next.parse::<usize>().is_ok(),
        None => value.is_array(),
    };
    match LISTS.iter().find(|(short, _)| short == first) {
        Some((short, full)) if listed || *short != "material" => std::iter::once(full.to_string())
            .chain(rest.iter().cloned())
            .collect(),
        _ => path.to_vec(),
    }
}

/// `flat` (a scene file's table) with each short form replaced by the key it stands for. A key
/// given in both forms is refused, naming both.
pub fn nest(flat: toml::Table) -> Result<toml::Table> {
    let mut nested = toml::Table::new();
    for (key, value) in flat {
        let path = full_path(std::slice::from_ref(&key), &value);
        match (path.as_slice(), value) {
            ([table, field], value) => put(&mut nested, table, field, value, &key)?,
            ([name], toml::Value::Table(fields)) if TABLES.contains(&name.as_str()) => {
                for (field, value) in fields {
                    let given = format!("{name}.{field}");
                    put(&mut nested, name, &field, value, &given)?;
                }
            }
            ([name], value) => {
                known_at_top(name)?;
                if nested.insert(name.clone(), value).is_some() {
                    return Err(twice(name, &key));
                }
            }
            _ => unreachable!("a key expands to one or two keys"),
        }
    }
    Ok(nested)
}

/// Sets `field` of `table` in `nested` to `value`, given as `given` (for errors).
fn put(
    nested: &mut toml::Table,
    table: &str,
    field: &str,
    value: toml::Value,
    given: &str,
) -> Result<()> {
    let entry = nested
        .entry(table)
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    let toml::Value::Table(fields) = entry else {
        return Err(twice(table, given));
    };
    match fields.insert(field.to_owned(), value) {
        Some(_) => Err(twice(&format!("{table}.{field}"), given)),
        None => Ok(()),
    }
}

/// Refuses `key` (the first key of a full path, short forms expanded) where it is not a key a
/// scene holds at its top.
pub(super) fn known_at_top(key: &str) -> Result<()> {
    match TOP_LEVEL.contains(&key) {
        true => Ok(()),
        false => Err(unknown(key)),
    }
}

/// The error of `key`, which is neither a table of a scene nor a short form: names the nearest
/// key that is, where one is near.
fn unknown(key: &str) -> Error {
    let known = TOP_LEVEL
        .iter()
        .copied()
        .chain(SHORT_FORMS.iter().map(|(short, _, _)| *short))
        .chain(LISTS.iter().map(|(short, _)| *short));
    let nearest = known
        .map(|k| (strsim::normalized_damerau_levenshtein(key, k), k))
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .filter(|(likeness, _)| *likeness >= 0.6);
    let hint = match nearest {
        Some((_, k)) => format!("did you mean {k}?"),
        None => "a key is one of the tables (run, source, domain, material, …) or a short form of \
                 one of their keys (spheres, dt, friction, …; docs/guide/simulate.md lists them)"
            .to_owned(),
    };
    Error::InvalidConfig {
        what: format!("scene key {key}"),
        reason: format!("is not a key of a scene: {hint}"),
    }
}

/// The error of `key` given twice, once as `given`.
fn twice(key: &str, given: &str) -> Error {
    let both = match key == given {
        true => String::new(),
        false => format!(" (also as {given}, its short form)"),
    };
    Error::InvalidConfig {
        what: format!("scene key {key}"),
        reason: format!("is given twice{both}: give it once"),
    }
}

/// The scene a checkpoint saved in the flat format, in the full one. That format wrote
/// `spheres`, `seed` and the `mesh_` keys whatever the scene, and no `contact` while `linear`
/// was the default; the keys its scene does not take are left out, and a scene without a
/// contact law is `linear`. A scene saved in the full format is returned as it is.
pub fn saved_scene(mut saved: toml::Table) -> Result<toml::Table> {
    if saved.contains_key("source") || TABLES.iter().any(|t| saved.contains_key(*t)) {
        return nest(saved);
    }
    let scene = saved
        .get("scene")
        .and_then(toml::Value::as_str)
        .unwrap_or("pour");
    let unused: &[&str] = match scene {
        "mesh" => &["spheres"],
        "input" => &[
            "spheres",
            "seed",
            "mesh_radius",
            "mesh_mixed",
            "mesh_size",
            "mesh_copies",
        ],
        _ => &["mesh_radius", "mesh_mixed", "mesh_size", "mesh_copies"],
    };
    for key in unused {
        saved.remove(*key);
    }
    saved
        .entry("contact")
        .or_insert_with(|| toml::Value::String("linear".into()));
    nest(saved)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn path(key: &str, value: toml::Value) -> String {
        let parts: Vec<String> = key.split('.').map(str::to_owned).collect();
        full_path(&parts, &value).join(".")
    }

    #[test]
    fn short_forms_stand_for_one_key_of_one_table_and_name_it_back() {
        let one = toml::Value::Integer(1);
        assert_eq!(path("friction", one.clone()), "material.friction");
        assert_eq!(path("mesh_copies", one.clone()), "source.copies");
        assert_eq!(path("spheres", one.clone()), "source.spheres");
        assert_eq!(path("inflow.0.rate", one.clone()), "inflow.0.rate");
        assert_eq!(
            path("material.1.friction", one.clone()),
            "materials.1.friction"
        );
        assert_eq!(path("material.friction", one.clone()), "material.friction");
        assert_eq!(path("material", toml::Value::Array(vec![])), "materials");
        assert_eq!(path("material_pair", one.clone()), "material_pairs");
        assert_eq!(path("run.steps", one), "run.steps");
        for (short, table, key) in SHORT_FORMS {
            assert_eq!(short_form(table, key), Some(short));
        }
        assert_eq!(short_form("source", "colour"), None);
    }

    #[test]
    fn a_flat_file_nests_and_a_key_given_in_both_forms_is_refused() {
        let flat: toml::Table = "steps = 3\nfriction = 0.2\n[material]\ndensity = 9.0\n"
            .parse()
            .unwrap();
        let nested = nest(flat).unwrap();
        assert_eq!(nested["run"]["steps"].as_integer(), Some(3));
        assert_eq!(nested["material"]["friction"].as_float(), Some(0.2));
        assert_eq!(nested["material"]["density"].as_float(), Some(9.0));
        let both: toml::Table = "friction = 0.2\n[material]\nfriction = 0.3\n"
            .parse()
            .unwrap();
        let e = nest(both).unwrap_err().to_string();
        assert!(
            e.contains("material.friction") && e.contains("twice"),
            "{e}"
        );
    }

    #[test]
    fn an_unknown_key_is_refused_with_the_nearest_known_one() {
        let refused = |text: &str| nest(text.parse().unwrap()).unwrap_err().to_string();
        let e = refused("frcition = 0.2\n");
        assert!(
            e.contains("frcition") && e.contains("did you mean friction?"),
            "{e}"
        );
        let e = refused("[domian]\ngravity = [0.0, 0.0, -9.81]\n");
        assert!(e.contains("did you mean domain?"), "{e}");
        let e = refused("steps = 3\nnosuchkey = 1\n");
        assert!(e.contains("nosuchkey") && e.contains("short form"), "{e}");
        assert!(!e.contains("did you mean"), "{e}");
        // Every table, list and short form is known.
        let mut every = String::new();
        for key in TOP_LEVEL.iter().filter(|k| !TABLES.contains(k)) {
            every += &format!("{key} = []\n");
        }
        for (short, _, _) in SHORT_FORMS {
            every += &format!("{short} = 1\n");
        }
        for table in TABLES.iter().filter(|t| **t != "material") {
            every += &format!("[{table}]\n");
        }
        let nested = nest(every.parse().unwrap()).unwrap();
        assert!(nested.keys().all(|k| TOP_LEVEL.contains(&k.as_str())));
    }
}
