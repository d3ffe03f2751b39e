//! `mimic rig new --overrides FILE`: hand values merged into a generated rig's TOML.
//!
//! Tables merge key by key (recursively, inline tables too); any other value, arrays and
//! arrays of tables (`frozen`, `[[morph_targets]]`) included, replaces the generated one whole.
//! `[[controls]]` are the exception: each override entry names its control (`fdp` or
//! `control`) and replaces or adds that control's keys; an unknown control is appended. An
//! override value keeps the comments written above and beside it in the override file, so the
//! reason for each hand value travels into the rig. Tables an override adds are written after
//! the generated ones.

use crate::RigNewError;
use std::path::Path;
use toml_edit::{DocumentMut, Item, Table, Value};

/// One step of a key path: a key, or the control named `fdp` / `control` in `[[controls]]`.
#[derive(Clone, Debug, PartialEq)]
enum Step {
    /// A table key.
    Key(String),
    /// An entry of `[[controls]]`, by its index in the merged array and its name.
    Control(usize, String),
}

/// A key path as written in messages: `solver.kernel`, `controls[5.1].vertex`.
fn dotted(path: &[Step]) -> String {
    let mut s = String::new();
    for step in path {
        match step {
            Step::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            Step::Control(_, name) => {
                s.push('[');
                s.push_str(name);
                s.push(']');
            }
        }
    }
    s
}

/// 1-based line of byte `offset` in `text`.
fn line_of(text: &str, offset: usize) -> usize {
    text.get(..offset)
        .map_or(1, |t| t.matches('\n').count() + 1)
}

/// Merges the override files, in order, into the generated rig TOML `generated`; after each,
/// the merged rig must load as `rig_path` (its mesh is resolved from there). Errors name the
/// override file and the key.
pub fn apply_overrides(
    generated: &str,
    overrides: &[(&Path, &str)],
    rig_path: &Path,
) -> Result<String, RigNewError> {
    let mut doc: DocumentMut = generated
        .parse()
        .map_err(|e| RigNewError::Frame(format!("the generated rig is not TOML: {e}")))?;
    let mut text = generated.to_string();
    for (path, over_text) in overrides {
        let fail = |key: &str, message: String| RigNewError::Override {
            path: path.to_path_buf(),
            key: key.to_string(),
            message,
        };
        let over: DocumentMut = over_text.parse().map_err(|e: toml_edit::TomlError| {
            let line = e.span().map_or(1, |s| line_of(over_text, s.start));
            RigNewError::OverrideSyntax {
                path: path.to_path_buf(),
                line,
                message: e.message().to_string(),
            }
        })?;
        let mut set = Vec::new();
        merge_table(
            doc.as_table_mut(),
            over.as_table(),
            &mut Vec::new(),
            &mut set,
        )
        .map_err(|(key, message)| fail(&key, message))?;
        order_tables(doc.as_table_mut());
        text = doc.to_string();
        if let Err(e) = mimic_assets::parse_rig(rig_path, &text) {
            let key = asset_line(&e)
                .and_then(|line| key_at_line(&text, &set, line))
                .unwrap_or_else(|| {
                    set.first()
                        .map_or_else(|| "(none)".to_string(), |p| dotted(p))
                });
            return Err(fail(
                &key,
                format!("with this override the rig does not load: {e}"),
            ));
        }
    }
    Ok(text)
}

/// The line an asset error points at, where it has one.
fn asset_line(e: &mimic_assets::AssetError) -> Option<usize> {
    use mimic_assets::AssetError as E;
    match e {
        E::Toml { line, .. }
        | E::Rig { line, .. }
        | E::Setting { line, .. }
        | E::Refused { line, .. } => Some(*line),
        _ => None,
    }
}

/// Of the key paths an override set, the one written last at or before `line` of `text`.
fn key_at_line(text: &str, set: &[Vec<Step>], line: usize) -> Option<String> {
    let doc = toml_edit::Document::parse(text).ok()?;
    let mut best: Option<(usize, String)> = None;
    for path in set {
        let Some(at) = item_at(doc.as_table(), path) else {
            continue;
        };
        let l = line_of(text, at);
        if l <= line && best.as_ref().is_none_or(|(b, _)| l >= *b) {
            best = Some((l, dotted(path)));
        }
    }
    best.map(|(_, k)| k)
}

/// Byte offset of the item at `path` in a parsed document (of the nearest enclosing item with a
/// position where it has none).
fn item_at(root: &Table, path: &[Step]) -> Option<usize> {
    let mut table: Option<&Table> = Some(root);
    let mut item: Option<&Item> = None;
    let mut at = None;
    for step in path {
        let next = match step {
            Step::Key(k) => match (table, item) {
                (Some(t), _) => t.get(k)?,
                (None, Some(i)) => i.get(k.as_str())?,
                (None, None) => return at,
            },
            Step::Control(i, _) => {
                let t = root.get("controls")?.as_array_of_tables()?.get(*i)?;
                at = t.span().map(|s| s.start).or(at);
                (table, item) = (Some(t), None);
                continue;
            }
        };
        at = next.span().map(|s| s.start).or(at);
        (table, item) = (next.as_table(), Some(next));
    }
    at
}

/// A table's or inline table's keys, for merging either form.
enum Tab<'a> {
    /// A `[table]`.
    Table(&'a mut Table),
    /// An `{ inline = table }`.
    Inline(&'a mut toml_edit::InlineTable),
}

/// Merges `over` into `base` (see the module comment); `path` is where `base` sits, `set`
/// collects the key paths written. Errors: (key, message).
fn merge_table(
    base: &mut Table,
    over: &Table,
    path: &mut Vec<Step>,
    set: &mut Vec<Vec<Step>>,
) -> Result<(), (String, String)> {
    for (k, item) in over.iter() {
        let Some((key, _)) = over.get_key_value(k) else {
            continue;
        };
        path.push(Step::Key(k.to_string()));
        if path.len() == 1 && k == "controls" {
            merge_controls(base, item, path, set)?;
        } else if let Some(sub) = base.get_mut(k).and_then(as_tab)
            && is_table(item)
        {
            merge_into(sub, item, path, set)?;
            take_comments(base, key, item);
        } else {
            base.insert_formatted(key, fresh(item.clone()));
            set.push(path.clone());
        }
        path.pop();
    }
    Ok(())
}

/// After merging the table `over` into `base[key]`: a merged inline table takes the override's
/// comments (above and beside it; the generated ones describe the generated values), a merged
/// `[table]` its header comment where the override writes one.
fn take_comments(base: &mut Table, key: &toml_edit::Key, over: &Item) {
    let commented = |d: &toml_edit::Decor| {
        d.prefix()
            .and_then(toml_edit::RawString::as_str)
            .is_some_and(|s| s.contains('#'))
    };
    match (base.get_mut(key.get()), over) {
        (Some(Item::Table(b)), Item::Table(o)) if commented(o.decor()) => {
            *b.decor_mut() = o.decor().clone();
        }
        (Some(Item::Value(b)), Item::Value(o)) => {
            *b.decor_mut() = o.decor().clone();
            if let Some(mut k) = base.key_mut(key.get()) {
                *k.leaf_decor_mut() = key.leaf_decor().clone();
            }
        }
        _ => {}
    }
}

/// `item` as a mergeable table, if it is one.
fn as_tab(item: &mut Item) -> Option<Tab<'_>> {
    match item {
        Item::Table(t) => Some(Tab::Table(t)),
        Item::Value(Value::InlineTable(t)) => Some(Tab::Inline(t)),
        _ => None,
    }
}

/// Whether `item` is a table of either form.
fn is_table(item: &Item) -> bool {
    matches!(item, Item::Table(_) | Item::Value(Value::InlineTable(_)))
}

/// Merges the table `over` (either form) into `base` (either form), key by key.
fn merge_into(
    base: Tab<'_>,
    over: &Item,
    path: &mut Vec<Step>,
    set: &mut Vec<Vec<Step>>,
) -> Result<(), (String, String)> {
    let pairs: Vec<(toml_edit::Key, Item)> = match over {
        Item::Table(t) => t
            .iter()
            .filter_map(|(k, _)| t.get_key_value(k))
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect(),
        Item::Value(Value::InlineTable(t)) => t
            .iter()
            .filter_map(|(k, _)| t.get_key_value(k))
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect(),
        _ => Vec::new(),
    };
    match base {
        Tab::Table(base) => {
            let mut over_table = Table::new();
            for (k, v) in pairs {
                over_table.insert_formatted(&k, v);
            }
            merge_table(base, &over_table, path, set)
        }
        Tab::Inline(base) => {
            for (k, v) in pairs {
                path.push(Step::Key(k.get().to_string()));
                let merged_sub = match (base.get_mut(k.get()), &v) {
                    (Some(Value::InlineTable(sub)), Item::Value(Value::InlineTable(_))) => {
                        merge_into(Tab::Inline(sub), &v, path, set)?;
                        true
                    }
                    _ => false,
                };
                if !merged_sub {
                    let Item::Value(value) = v else {
                        return Err((
                            dotted(path),
                            "a [table] cannot go inside an inline table; write it inline".into(),
                        ));
                    };
                    base.insert_formatted(&k, value);
                    set.push(path.clone());
                }
                path.pop();
            }
            Ok(())
        }
    }
}

/// Merges override `[[controls]]` entries into the generated ones, matched by `fdp` or
/// `control`.
fn merge_controls(
    base: &mut Table,
    over: &Item,
    path: &mut Vec<Step>,
    set: &mut Vec<Vec<Step>>,
) -> Result<(), (String, String)> {
    let Some(entries) = over.as_array_of_tables() else {
        return Err((
            "controls".into(),
            "write overridden controls as [[controls]] tables, each naming its fdp".into(),
        ));
    };
    let Some(controls) = base
        .get_mut("controls")
        .and_then(Item::as_array_of_tables_mut)
    else {
        return Err((
            "controls".into(),
            "the generated rig has no [[controls]]".into(),
        ));
    };
    for (n, entry) in entries.iter().enumerate() {
        let name = control_name(entry).ok_or_else(|| {
            (
                format!("controls[{n}]"),
                "an overridden control needs `fdp` (or `control`) to say which it is".into(),
            )
        })?;
        let found = controls
            .iter()
            .position(|c| control_name(c).as_deref() == Some(name.as_str()));
        let index = match found {
            Some(i) => i,
            None => {
                controls.push(Table::new());
                controls.len() - 1
            }
        };
        let Some(target) = controls.get_mut(index) else {
            continue;
        };
        if found.is_none() {
            *target.decor_mut() = entry.decor().clone();
            target.set_position(None);
        }
        path.push(Step::Control(index, name.clone()));
        for (k, item) in entry.iter() {
            let Some((key, _)) = entry.get_key_value(k) else {
                continue;
            };
            path.push(Step::Key(k.to_string()));
            target.insert_formatted(key, fresh(item.clone()));
            if k != "fdp" && k != "control" {
                set.push(path.clone());
            }
            path.pop();
        }
        path.pop();
    }
    Ok(())
}

/// A control table's name: its `fdp`, else its `control`.
fn control_name(t: &Table) -> Option<String> {
    t.get("fdp")
        .or_else(|| t.get("control"))
        .and_then(Item::as_str)
        .map(str::to_string)
}

/// Numbers the tables in the order a rig is read: `[regions]`, `[solver]`, `[look]`, any
/// other, `[[controls]]`, `[[morph_targets]]` (a table's subtables right after it).
fn order_tables(root: &mut Table) {
    fn number(t: &mut Table, next: &mut isize) {
        t.set_position(Some(*next));
        *next += 1;
        for (_, v) in t.iter_mut() {
            number_item(v, next);
        }
    }
    fn number_item(item: &mut Item, next: &mut isize) {
        match item {
            Item::Table(t) => number(t, next),
            Item::ArrayOfTables(a) => a.iter_mut().for_each(|t| number(t, next)),
            _ => {}
        }
    }
    const FIRST: [&str; 3] = ["regions", "solver", "look"];
    const LAST: [&str; 2] = ["controls", "morph_targets"];
    let keys: Vec<String> = root.iter().map(|(k, _)| k.to_string()).collect();
    let rank = |k: &str| {
        FIRST
            .iter()
            .position(|f| *f == k)
            .or_else(|| LAST.iter().position(|l| *l == k).map(|i| 100 + i))
            .unwrap_or(50)
    };
    let mut sorted = keys;
    sorted.sort_by_key(|k| rank(k));
    let mut next = 1;
    for k in sorted {
        if let Some(item) = root.get_mut(&k) {
            number_item(item, &mut next);
        }
    }
}

/// An item from an override made ready for the generated document: its tables lose their
/// places in the override file, so they are written after the generated tables.
fn fresh(mut item: Item) -> Item {
    fn unplace(t: &mut Table) {
        t.set_position(None);
        for (_, v) in t.iter_mut() {
            match v {
                Item::Table(sub) => unplace(sub),
                Item::ArrayOfTables(a) => a.iter_mut().for_each(unplace),
                _ => {}
            }
        }
    }
    match &mut item {
        Item::Table(t) => unplace(t),
        Item::ArrayOfTables(a) => a.iter_mut().for_each(unplace),
        _ => {}
    }
    item
}

#[cfg(test)]
mod tests {
    use super::*;

    fn merged(base: &str, over: &str) -> Result<String, (String, String)> {
        let mut doc: DocumentMut = base.parse().unwrap();
        let over: DocumentMut = over.parse().unwrap();
        let mut set = Vec::new();
        merge_table(
            doc.as_table_mut(),
            over.as_table(),
            &mut Vec::new(),
            &mut set,
        )?;
        Ok(doc.to_string())
    }

    #[test]
    fn tables_merge_arrays_replace_and_controls_match_by_name() {
        let base = "name = \"g\"\nfrozen = [[1, 2], [5, 6]]\n\n[regions]\ntop_from = 2.2  # generated\nband = 1.3\n\n[solver]\nkernel = { kind = \"exponential\", radius = 2.5 }\n\n[[controls]]\nfdp = \"5.1\"\nvertex = 10\nnote = \"rule\"\n\n[[controls]]\nfdp = \"5.2\"\nvertex = 11\n";
        let over = "# why the range\nfrozen = [[1, 9]]\n\n[regions]\n# hand\ntop_from = 2.3\n\n[solver]\nkernel = { radius = 2.0 }\n\n[[controls]]\nfdp = \"5.2\"\nvertex = 12  # hand pick\n\n[look]\nhidden = [[3, 4]]\n";
        let out = merged(base, over).unwrap();
        let expect = "name = \"g\"\n# why the range\nfrozen = [[1, 9]]\n\n[regions]\n# hand\ntop_from = 2.3\nband = 1.3\n\n[solver]\nkernel = { kind = \"exponential\", radius = 2.0 }\n\n[[controls]]\nfdp = \"5.1\"\nvertex = 10\nnote = \"rule\"\n\n[[controls]]\nfdp = \"5.2\"\nvertex = 12  # hand pick\n\n[look]\nhidden = [[3, 4]]\n";
        assert_eq!(out, expect);
    }

    #[test]
    fn a_control_without_a_name_or_a_table_in_an_inline_table_is_an_error() {
        let base =
            "[solver]\nkernel = { radius = 2.5 }\n\n[[controls]]\nfdp = \"5.1\"\nvertex = 10\n";
        let (key, message) = merged(base, "[[controls]]\nvertex = 3\n").unwrap_err();
        assert_eq!(key, "controls[0]");
        assert!(message.contains("fdp"), "{message}");
        let (key, _) = merged(base, "[solver.kernel.x]\ny = 1\n").unwrap_err();
        assert_eq!(key, "solver.kernel.x");
        let out = merged(base, "[[controls]]\nfdp = \"9.9\"\nvertex = 3\n").unwrap();
        assert!(
            out.ends_with("[[controls]]\nfdp = \"9.9\"\nvertex = 3\n"),
            "{out}"
        );
    }
}
