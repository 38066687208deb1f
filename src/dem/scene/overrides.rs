//! Scene fields set over a scene file: `--set key=value` assignments and Python's dicts.

use super::short_forms::{full_path, known_at_top};
use crate::error::{Error, Result};

/// Scene fields set over a scene file and the flags, in order: from `--set key=value`
/// assignments ([`Overrides::parse`]) or from a table of fields ([`Overrides::from_table`], as
/// Python's scene dict is), so a value is read once, by the scene's own deserialization. A
/// dotted key reaches into the scene's tables: `inflow.0.rate=3000` sets the rate of the first
/// `[[inflow]]` table and leaves its other fields as they are.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides(Vec<(Vec<String>, toml::Value)>);

impl Overrides {
    /// From `key=value` assignments, in order (`value` in TOML syntax; a bare word is taken as
    /// a string, so `scene=slab` works; `key` a field, or a dotted path into a table or an
    /// array of tables by index).
    pub fn parse(assignments: &[impl AsRef<str>]) -> Result<Self> {
        assignments
            .iter()
            .map(|a| parse_override(a.as_ref()))
            .collect::<Result<_>>()
            .map(Overrides)
    }

    /// From a table of fields (each key a field of the scene file, each value as the file
    /// would give it): a table's fields are set one by one (`{"material": {"friction": 0.3}}`
    /// sets `material.friction` and keeps the material's other keys), a list of tables whole.
    pub fn from_table(table: toml::Table) -> Self {
        let mut fields = Vec::new();
        leaves(Vec::new(), table, &mut fields);
        Overrides(fields)
    }

    /// These, then `more` (whose fields win where both set one).
    pub fn then(mut self, more: Overrides) -> Overrides {
        self.0.extend(more.0);
        self
    }

    /// Whether no field is set.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Sets each field in `table` (a scene's, in the full form), in order, a short form where
    /// it stands for (`short_forms`): a field replaced whole, a dotted path set where it leads (tables on the way made where missing; an index of an array of tables
    /// must name one of them).
    pub(super) fn apply(&self, table: &mut toml::Table) -> Result<()> {
        for (path, value) in &self.0 {
            let full = full_path(path, value);
            known_at_top(&full[0])?;
            set_at(table, &full, &path.join("."), value)?;
        }
        Ok(())
    }
}

/// Each field of `table` (under `path`) with its value, a table's by its own fields.
fn leaves(path: Vec<String>, table: toml::Table, out: &mut Vec<(Vec<String>, toml::Value)>) {
    for (key, value) in table {
        let mut at = path.clone();
        at.push(key);
        match value {
            toml::Value::Table(inner) => leaves(at, inner, out),
            value => out.push((at, value)),
        }
    }
}

/// Sets `value` at `path` (at least one key) under `table`; `key` is the whole path, for errors.
fn set_at(table: &mut toml::Table, path: &[String], key: &str, value: &toml::Value) -> Result<()> {
    let bad = |reason: String| Error::InvalidConfig {
        what: format!("--set {key}"),
        reason,
    };
    let (first, rest) = path.split_first().expect("a key has a name");
    if rest.is_empty() {
        table.insert(first.clone(), value.clone());
        return Ok(());
    }
    let indexed = rest[0].parse::<usize>().is_ok();
    if indexed && !table.contains_key(first) {
        return Err(bad(format!("there are no {first} tables here to index")));
    }
    match table
        .entry(first.clone())
        .or_insert_with(|| toml::Value::Table(toml::Table::new()))
    {
        toml::Value::Table(inner) => set_at(inner, rest, key, value),
        toml::Value::Array(items) => {
            let (index, after) = rest.split_first().expect("rest is not empty");
            let k: usize = index.parse().map_err(|_| {
                bad(format!(
                    "{first} is a list of tables: the part after it is an index, from 0"
                ))
            })?;
            let len = items.len();
            match items.get_mut(k) {
                Some(toml::Value::Table(inner)) if !after.is_empty() => {
                    set_at(inner, after, key, value)
                }
                Some(toml::Value::Table(_)) => Err(bad(format!(
                    "{first}.{k} is a table: name the field of it to set"
                ))),
                Some(other) => Err(bad(format!("{first}.{k} is {other}, not a table"))),
                None => Err(bad(format!(
                    "there are {len} {first} tables here, {first}.0 to {first}.{}",
                    len.saturating_sub(1)
                ))),
            }
        }
        other => Err(bad(format!("{first} is {other}, not a table"))),
    }
}

/// Parses a `key=value` override (`value` in TOML syntax; a bare word is taken as a string, so
/// `scene=slab` works; `key` a field or a dotted path of fields and indices).
fn parse_override(assignment: &str) -> Result<(Vec<String>, toml::Value)> {
    let bad = |reason: String| Error::InvalidConfig {
        what: format!("--set {assignment:?}"),
        reason,
    };
    let (key, value) = assignment
        .split_once('=')
        .ok_or_else(|| bad("expected key=value".into()))?;
    let key = key.trim();
    let path: Vec<String> = key.split('.').map(str::to_owned).collect();
    let named = |part: &String| {
        !part.is_empty() && part.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
    };
    if !path.iter().all(named) || path[0].chars().all(|c| c.is_ascii_digit()) {
        return Err(bad(format!("{key:?} is not a field name")));
    }
    let value = value.trim();
    let parsed: toml::Value = match format!("v = {value}").parse::<toml::Table>() {
        Ok(mut t) => t.remove("v").expect("parsed the key v"),
        Err(_) if is_integer(value) => {
            return Err(bad(format!(
                "{value} is outside the range of a scene integer ({} ..= {})",
                i64::MIN,
                i64::MAX
            )));
        }
        Err(_) => toml::Value::String(value.to_owned()),
    };
    Ok((path, parsed))
}

/// Whether `text` is an integer numeral (digits after an optional sign).
fn is_integer(text: &str) -> bool {
    let digits = text.strip_prefix(['+', '-']).unwrap_or(text);
    !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
}
