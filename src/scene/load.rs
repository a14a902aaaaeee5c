//! TOML text → [`SceneFile`], section by section, so that one bad material
//! or object does not hide the problems of the others.

use std::ops::Range;

use serde::de::DeserializeOwned;
use toml::Spanned;
use toml::de::{DeTable, DeValue, ValueDeserializer};

use super::error::Diagnostics;
use super::format::{ObjectDesc, SceneFile};
use super::tables::Tables;
use crate::limits::MAX_TABLE_TEXT;

const SECTIONS: &str = "`render`, `animation`, `camera`, `materials`, `lights` or `objects`";

/// Parses `source` into sections, recording every problem found in `diags`;
/// the `[[objects]]` tables are only located (see [`object`]). Returns
/// `None` for a syntax error outside them (nothing after it can be trusted).
pub fn parse(source: &str, diags: &mut Diagnostics) -> Option<SceneFile> {
    let tables = Tables::find(source);
    let rest_len = tables.rest_len(source.len());
    if rest_len > MAX_TABLE_TEXT {
        diags.error(
            0..0,
            too_large("the scene's text outside [[objects]] tables", rest_len),
        );
        return None;
    }
    let rest = tables.rest(source);
    let (doc, errors) = DeTable::parse_recoverable(rest.as_deref().unwrap_or(source));
    if !errors.is_empty() {
        report_syntax(errors, diags);
        return None;
    }
    let mut file = SceneFile::default();
    for (key, value) in doc.get_ref() {
        match key.get_ref().as_ref() {
            "render" => file.render = deserialize(value, diags).unwrap_or_default(),
            "animation" => file.animation = deserialize(value, diags),
            "camera" => {
                file.camera = deserialize(value, diags);
                if file.camera.is_none() {
                    file.unparsed.insert("camera".into());
                }
            }
            "materials" => {
                for (name, v) in named_entries(value, "materials", diags) {
                    if let Some(m) = deserialize(v, diags) {
                        file.materials.insert(name, m);
                    } else {
                        file.unparsed.insert(format!("materials.{name}"));
                    }
                }
            }
            "lights" => {
                for (name, v) in named_entries(value, "lights", diags) {
                    if let Some(l) = deserialize(v, diags) {
                        file.lights.insert(name, l);
                    }
                }
            }
            "objects" if !tables.objects.is_empty() => diags.error(
                key.span(),
                "`objects` is given here and also as [[objects]] tables; use one form",
            ),
            "objects" => match value.get_ref() {
                DeValue::Array(items) => {
                    file.objects = items.iter().filter_map(|v| deserialize(v, diags)).collect();
                }
                other => diags.error(
                    value.span(),
                    format!(
                        "`objects` must be an array of tables ([[objects]]), found {}",
                        other.type_str()
                    ),
                ),
            },
            other => diags.error(
                key.span(),
                format!("unknown section `{other}`, expected {SECTIONS}"),
            ),
        }
    }
    file.object_tables = tables.objects;
    Some(file)
}

/// Parses the one `[[objects]]` table at `range` of the source. Spans are
/// relative to `range.start`: the caller sets that offset on `diags` (and
/// keeps it while building the object, whose spans are relative too).
pub fn object(range: Range<usize>, diags: &mut Diagnostics) -> Option<Spanned<ObjectDesc>> {
    if range.len() > MAX_TABLE_TEXT {
        diags.error(0..0, too_large("this object's table", range.len()));
        return None;
    }
    let text = diags.source().get(range).unwrap_or_default();
    let (doc, errors) = DeTable::parse_recoverable(text);
    if !errors.is_empty() {
        report_syntax(errors, diags);
        return None;
    }
    // The text is one `[[objects]]` header with its keys and sub-tables.
    let item = doc.get_ref().iter().find_map(|(key, value)| {
        match (key.get_ref().as_ref(), value.get_ref()) {
            ("objects", DeValue::Array(items)) => items.first(),
            _ => None,
        }
    })?;
    deserialize(item, diags)
}

/// The message for text over [`MAX_TABLE_TEXT`].
fn too_large(what: &str, bytes: usize) -> String {
    format!(
        "{what} is {} MiB of text; at most {} MiB is read \
         (large geometry belongs in a model file: type = \"mesh\")",
        bytes >> 20,
        MAX_TABLE_TEXT >> 20
    )
}

/// Records the TOML parser's syntax errors.
fn report_syntax(errors: Vec<toml::de::Error>, diags: &mut Diagnostics) {
    for e in errors {
        let span = e.span().unwrap_or(0..0);
        let message = match e.message() {
            // The parser does not say which key; the span points at it.
            "duplicate key" => format!(
                "duplicate key `{}`: each key may appear once in a table",
                diags.text_at(span.clone(), 60).trim()
            ),
            // The TOML reader's own bound on nested tables and arrays.
            m if m.contains("recurs") => format!(
                "tables nested too deep for the TOML reader ({m}); CSG written as \
                 [[objects.children]] tables may nest {} deep, fewer when written inline",
                crate::limits::MAX_CSG_DEPTH
            ),
            m => m.to_string(),
        };
        diags.error(span, message);
    }
}

/// The entries of a `[section.NAME]` table.
fn named_entries<'a, 'i>(
    value: &'a Spanned<DeValue<'i>>,
    section: &str,
    diags: &mut Diagnostics,
) -> Vec<(String, &'a Spanned<DeValue<'i>>)> {
    match value.get_ref() {
        DeValue::Table(t) => t
            .iter()
            .map(|(k, v)| (k.get_ref().to_string(), v))
            .collect(),
        other => {
            diags.error(
                value.span(),
                format!(
                    "`{section}` must be a table of named entries ([{section}.NAME]), found {}",
                    other.type_str()
                ),
            );
            Vec::new()
        }
    }
}

/// Deserializes one value, recording the error (with its span, or the
/// value's span when serde gives none) on failure.
fn deserialize<T: DeserializeOwned>(
    value: &Spanned<DeValue<'_>>,
    diags: &mut Diagnostics,
) -> Option<T> {
    match T::deserialize(ValueDeserializer::from(value.clone())) {
        Ok(v) => Some(v),
        Err(e) => {
            diags.error(e.span().unwrap_or(value.span()), e.message().to_string());
            None
        }
    }
}
