//! Scenes given as data rather than text: a Python dict (`Scene.from_dict`)
//! or anything else that holds what TOML holds. The values go straight
//! into the file format's serde structs ([`format`](super::format)) and
//! through the same checks and build as a scene file, without TOML text
//! written and parsed again.
//!
//! Problems are located by key path (`objects[3].radius`,
//! `materials.glass.ior`) instead of line and column: every table, array
//! and value of a table gets a node number, used as its span, and a
//! problem's span is turned back into the path of its node.
//!
//! Objects are fed one at a time ([`DictScene::object`]) and each is turned
//! into its `ObjectDesc` at once, so a million of them never stand as a
//! million syntax trees.
//!
//! Every walk of a value here recurses once per table or list it nests
//! (the digest, the TOML values, serde's structs, dropping them), so a
//! value nested deeper than [`MAX_NESTING`] is refused, by its key path,
//! before any of them: the check and the refusal walk with a stack of
//! their own, never the thread's.

use std::borrow::Cow;
use std::collections::HashMap;
use std::path::Path;

use serde::de::DeserializeOwned;
use sha2::{Digest, Sha256};
use toml::Spanned;
use toml::de::{DeArray, DeTable, DeValue, ValueDeserializer};

use super::error::Diagnostics;
use super::format::SceneFile;
use super::{LoadOptions, Scene, build};
use crate::limits::MAX_CSG_DEPTH;
use crate::text::escape_controls;

/// How deeply tables and lists may nest in one object or one section's
/// value (the object's table, or the section's, is level 1; a section's
/// own list of objects is not counted). Each CSG operation costs two
/// levels, its table and its `children` list, so a CSG nested
/// [`MAX_CSG_DEPTH`] deep has its innermost parts' tables at level
/// `2 * MAX_CSG_DEPTH + 1` (129), and their values reach at most five
/// further (a keyed `transform`: list, step, keys, key, value; 134). The
/// margin lets CSG of a few operations more reach the builder, which
/// refuses them with its own message. The bound on every recursion over
/// a dict scene's values, far below what a thread's stack allows.
pub const MAX_NESTING: usize = 2 * MAX_CSG_DEPTH + 16;

/// The message for a value nested past [`MAX_NESTING`].
pub fn too_deep_message() -> String {
    format!(
        "tables and lists nested more than {MAX_NESTING} deep; Prism reads no deeper \
         (CSG nests at most {MAX_CSG_DEPTH} operations, two levels each: a table and its `children`)"
    )
}

const SECTIONS: &str = "`render`, `animation`, `camera`, `materials`, `lights` or `objects`";

/// A value of a scene given as data: what a TOML value can be.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// `true` or `false`.
    Bool(bool),
    /// An integer.
    Integer(i64),
    /// A float (infinities and NaN included, as TOML has them).
    Float(f64),
    /// A string.
    String(String),
    /// A list.
    Array(Vec<Value>),
    /// A table, its keys in order.
    Table(Vec<(String, Value)>),
}

/// One problem in a dict scene: where (a key path such as
/// `objects[3].radius`, empty for the scene as a whole) and what.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Problem {
    /// The key path of the value at fault, control characters escaped.
    pub key_path: String,
    /// What is wrong, without the path.
    pub message: String,
}

/// A step of a key path.
#[derive(Clone, Copy, Debug)]
enum Step {
    /// A key, by its number in `DictScene::keys`.
    Key(u32),
    /// An index into a list.
    Index(u32),
}

/// A scene being assembled from data: sections and objects in, then
/// [`finish`](Self::finish) checks and builds it.
pub struct DictScene {
    file: SceneFile,
    /// Node `n` (span `n..n + 1`): its parent node and its step from there.
    /// Node 0 is the scene itself.
    nodes: Vec<(u32, Step)>,
    keys: Vec<String>,
    key_ids: HashMap<String, u32>,
    /// Problems found before the build: (node, message).
    problems: Vec<(usize, String)>,
    /// The node of `objects`, once an object has been added.
    objects_node: Option<u32>,
    /// Objects added so far.
    objects: u32,
    /// Digest of every key and value, in order: the scene's "text".
    digest: Sha256,
    /// Scratch text for the numbers of one value (see [`numbers`]).
    scratch: String,
}

impl Default for DictScene {
    fn default() -> Self {
        DictScene::new()
    }
}

impl DictScene {
    /// An empty scene.
    pub fn new() -> Self {
        DictScene {
            file: SceneFile::default(),
            nodes: vec![(0, Step::Index(0))],
            keys: Vec::new(),
            key_ids: HashMap::new(),
            problems: Vec::new(),
            objects_node: None,
            objects: 0,
            digest: Sha256::new(),
            scratch: String::new(),
        }
    }

    /// Adds the section `name` (`render`, `camera`, `materials`, …; an
    /// `objects` list may come here whole or object by object through
    /// [`object`](Self::object)).
    pub fn section(&mut self, name: &str, value: Value) {
        self.digest.update(b"S");
        self.digest_str(name);
        if name == "objects"
            && let Value::Array(items) = value
        {
            for item in items {
                self.object(item);
            }
            return;
        }
        let node = self.node(0, name);
        let (numbers, deep) = numbers(&value, std::mem::take(&mut self.scratch));
        if deep {
            self.scratch = numbers;
            self.refuse_deep(node, value);
            return;
        }
        let mut parsed = parse_numbers(&numbers);
        let value = self.de_value(value, node, &mut parsed);
        drop(parsed);
        match name {
            "render" => self.file.render = self.deserialize(value).unwrap_or_default(),
            "animation" => self.file.animation = self.deserialize(value),
            "camera" => {
                self.file.camera = self.deserialize(value);
                if self.file.camera.is_none() {
                    self.file.unparsed.insert("camera".into());
                }
            }
            "materials" => {
                for (entry, v) in self.entries(value, name) {
                    match self.deserialize(v) {
                        Some(m) => {
                            self.file.materials.insert(entry, m);
                        }
                        None => {
                            self.file.unparsed.insert(format!("materials.{entry}"));
                        }
                    }
                }
            }
            "lights" => {
                for (entry, v) in self.entries(value, name) {
                    if let Some(l) = self.deserialize(v) {
                        self.file.lights.insert(entry, l);
                    }
                }
            }
            "objects" => {
                let found = value.get_ref().type_str();
                self.problem(
                    node,
                    format!("`objects` must be a list of tables, found {found}"),
                );
            }
            other => {
                let other = escape_controls(other).into_owned();
                self.problem(
                    node,
                    format!("unknown section `{other}`, expected {SECTIONS}"),
                );
            }
        }
        self.scratch = numbers;
    }

    /// Adds the next object of `objects`.
    pub fn object(&mut self, value: Value) {
        let parent = match self.objects_node {
            Some(n) => n,
            None => {
                let n = self.node(0, "objects");
                self.objects_node = Some(n);
                n
            }
        };
        self.digest.update(b"O");
        let node = self.push(parent, Step::Index(self.objects));
        self.objects += 1;
        let (numbers, deep) = numbers(&value, std::mem::take(&mut self.scratch));
        if deep {
            self.scratch = numbers;
            self.refuse_deep(node, value);
            return;
        }
        let mut parsed = parse_numbers(&numbers);
        let value = self.de_value(value, node, &mut parsed);
        drop(parsed);
        if let Some(o) = self.deserialize(value) {
            self.file.objects.push(o);
        }
        self.scratch = numbers;
    }

    /// Checks and builds the scene, with relative paths below `base_dir`;
    /// every problem found, by key path, if it is not valid. An open
    /// shutter on keyed values is refused here: its instants are the dict
    /// walked again, which [`finish_at`](Self::finish_at) builds one by one
    /// (the Python binding does).
    pub fn finish(self, base_dir: &Path, options: &LoadOptions) -> Result<Scene, Vec<Problem>> {
        let scene = self.finish_at(base_dir, options, 0.0)?;
        if scene.settings.shutter.is_some() && scene.animated {
            return Err(vec![Problem {
                key_path: "render.shutter".into(),
                message: "an open shutter on keyed values (motion blur) needs its instants \
                          built too: use DictScene::finish_at for each, or the scene as TOML text"
                    .into(),
            }]);
        }
        Ok(scene)
    }

    /// [`finish`](Self::finish) with keyed values `offset` frames after the
    /// frame `options` names (an instant of the shutter, see
    /// [`Scene::motion`]); no refusal of an open shutter.
    pub fn finish_at(
        self,
        base_dir: &Path,
        options: &LoadOptions,
        offset: f64,
    ) -> Result<Scene, Vec<Problem>> {
        let DictScene {
            file,
            nodes,
            keys,
            problems,
            digest,
            ..
        } = self;
        // One line per node: a span's line is its node.
        let lines = "\n".repeat(nodes.len());
        let mut diags = Diagnostics::new(&lines);
        for (node, message) in problems {
            diags.error(node..node + 1, message);
        }
        let checked = build::check_at(file, base_dir, options, offset, &mut diags);
        match checked {
            Some(mut checked) if diags.is_empty() => {
                let text: String = digest
                    .finalize()
                    .iter()
                    .map(|b| format!("{b:02x}"))
                    .collect();
                let inventory = checked.inventory_mut();
                inventory.content_hash = super::content_hash(&text, &inventory.files_read);
                Ok(checked.finish())
            }
            _ => Err(diags
                .into_diagnostics()
                .into_iter()
                .map(|d| {
                    let key_path = path_of(&nodes, &keys, d.line.saturating_sub(1));
                    let message = strip_label(&key_path, d.message);
                    Problem { key_path, message }
                })
                .collect()),
        }
    }

    fn push(&mut self, parent: u32, step: Step) -> u32 {
        let n = self.nodes.len() as u32;
        self.nodes.push((parent, step));
        n
    }

    fn node(&mut self, parent: u32, key: &str) -> u32 {
        let id = match self.key_ids.get(key) {
            Some(&id) => id,
            None => {
                let id = self.keys.len() as u32;
                self.keys.push(key.to_string());
                self.key_ids.insert(key.to_string(), id);
                id
            }
        };
        self.push(parent, Step::Key(id))
    }

    fn problem(&mut self, node: u32, message: String) {
        self.problems.push((node as usize, message));
    }

    /// Records that `value` (at `node`) nests past [`MAX_NESTING`], at the
    /// first table or list too deep, and drops it without recursing.
    fn refuse_deep(&mut self, node: u32, value: Value) {
        let at = self.deep_node(node, &value);
        self.problem(at, too_deep_message());
        dispose(value);
    }

    /// The node of the first table or list of `value` (in walk order)
    /// nested past [`MAX_NESTING`], with the nodes of the path to it;
    /// `node` if there is none.
    fn deep_node(&mut self, node: u32, value: &Value) -> u32 {
        enum Via<'a> {
            Key(&'a str),
            Index(usize),
        }
        // The tables and lists walked: (parent's number + 1, step).
        let mut walked: Vec<(usize, Via<'_>)> = Vec::new();
        let mut stack: Vec<(&Value, usize, usize)> = vec![(value, 1, 0)];
        let mut found = None;
        while let Some((v, depth, at)) = stack.pop() {
            if depth > MAX_NESTING {
                found = Some(at);
                break;
            }
            match v {
                Value::Array(items) => {
                    for (i, item) in items.iter().enumerate().rev() {
                        if matches!(item, Value::Array(_) | Value::Table(_)) {
                            walked.push((at, Via::Index(i)));
                            stack.push((item, depth + 1, walked.len()));
                        }
                    }
                }
                Value::Table(entries) => {
                    for (key, item) in entries.iter().rev() {
                        if matches!(item, Value::Array(_) | Value::Table(_)) {
                            walked.push((at, Via::Key(key)));
                            stack.push((item, depth + 1, walked.len()));
                        }
                    }
                }
                _ => {}
            }
        }
        let mut steps = Vec::new();
        let mut at = found.unwrap_or(0);
        while at != 0 {
            let (parent, step) = &walked[at - 1];
            steps.push(step);
            at = *parent;
        }
        let mut n = node;
        for step in steps.into_iter().rev() {
            n = match step {
                Via::Key(key) => self.node(n, key),
                Via::Index(i) => self.push(n, Step::Index(*i as u32)),
            };
        }
        n
    }

    fn digest_str(&mut self, s: &str) {
        self.digest.update((s.len() as u64).to_le_bytes());
        self.digest.update(s.as_bytes());
    }

    /// `value` as the TOML parser's value, each table, list and table
    /// entry a node of its own (a list's numbers and strings share the
    /// list's), its numbers taken in order from `numbers`.
    fn de_value<'b>(
        &mut self,
        value: Value,
        node: u32,
        numbers: &mut impl Iterator<Item = DeValue<'b>>,
    ) -> Spanned<DeValue<'b>> {
        let span = node as usize..node as usize + 1;
        let de = match value {
            Value::Bool(b) => {
                self.digest.update([b'b', u8::from(b)]);
                DeValue::Boolean(b)
            }
            Value::Integer(i) => {
                self.digest.update([b'i']);
                self.digest.update(i.to_le_bytes());
                numbers.next().unwrap_or(DeValue::Boolean(false))
            }
            Value::Float(f) => {
                self.digest.update([b'f']);
                self.digest.update(f.to_le_bytes());
                numbers.next().unwrap_or(DeValue::Boolean(false))
            }
            Value::String(s) => {
                self.digest.update([b's']);
                self.digest_str(&s);
                DeValue::String(Cow::Owned(s))
            }
            Value::Array(items) => {
                self.digest.update([b'a']);
                self.digest.update((items.len() as u64).to_le_bytes());
                let mut array = DeArray::new();
                for (i, item) in items.into_iter().enumerate() {
                    let item_node = match item {
                        Value::Array(_) | Value::Table(_) => self.push(node, Step::Index(i as u32)),
                        _ => node,
                    };
                    array.push(self.de_value(item, item_node, numbers));
                }
                DeValue::Array(array)
            }
            Value::Table(entries) => {
                self.digest.update([b't']);
                self.digest.update((entries.len() as u64).to_le_bytes());
                let mut table = DeTable::new();
                for (key, item) in entries {
                    self.digest_str(&key);
                    let item_node = self.node(node, &key);
                    let item_span = item_node as usize..item_node as usize + 1;
                    let v = self.de_value(item, item_node, numbers);
                    table.insert(Spanned::new(item_span, Cow::Owned(key)), v);
                }
                DeValue::Table(table)
            }
        };
        Spanned::new(span, de)
    }

    /// The entries of a `materials` or `lights` table.
    fn entries<'b>(
        &mut self,
        value: Spanned<DeValue<'b>>,
        section: &str,
    ) -> Vec<(String, Spanned<DeValue<'b>>)> {
        let span = value.span();
        match value.into_inner() {
            DeValue::Table(t) => t
                .into_iter()
                .map(|(k, v)| (k.into_inner().into_owned(), v))
                .collect(),
            other => {
                let found = other.type_str();
                self.problem(
                    span.start as u32,
                    format!("`{section}` must be a table of named entries, found {found}"),
                );
                Vec::new()
            }
        }
    }

    /// Deserializes one value, recording the problem on failure.
    fn deserialize<T: DeserializeOwned>(&mut self, value: Spanned<DeValue<'_>>) -> Option<T> {
        let span = value.span();
        match T::deserialize(ValueDeserializer::from(value)) {
            Ok(v) => Some(v),
            Err(e) => {
                let at = e.span().unwrap_or(span).start;
                self.problems.push((at, e.message().to_string()));
                None
            }
        }
    }
}

/// The numbers of `value`, in walk order, as the text of a TOML array
/// (written into `buffer`): the TOML parser's numbers are made by parsing,
/// so they are parsed once per value from their shortest exact text. With
/// `true` (the text unfinished) if `value` nests past [`MAX_NESTING`].
fn numbers(value: &Value, mut buffer: String) -> (String, bool) {
    use std::fmt::Write;
    buffer.clear();
    buffer.push('[');
    // (value, tables and lists above it), next to write on top.
    let mut stack: Vec<(&Value, usize)> = vec![(value, 0)];
    while let Some((v, above)) = stack.pop() {
        match v {
            Value::Integer(i) => {
                let _ = write!(buffer, "{i},");
            }
            Value::Float(f) if f.is_nan() => buffer.push_str("nan,"),
            Value::Float(f) if f.is_infinite() => {
                buffer.push_str(if *f > 0.0 { "inf," } else { "-inf," })
            }
            // `{:?}` is the shortest text that reads back as the same f64,
            // always with a `.` or an exponent: a TOML float.
            Value::Float(f) => {
                let _ = write!(buffer, "{f:?},");
            }
            Value::Array(_) | Value::Table(_) if above >= MAX_NESTING => return (buffer, true),
            Value::Array(items) => stack.extend(items.iter().rev().map(|i| (i, above + 1))),
            Value::Table(entries) => {
                stack.extend(entries.iter().rev().map(|(_, i)| (i, above + 1)))
            }
            Value::Bool(_) | Value::String(_) => {}
        }
    }
    buffer.push(']');
    (buffer, false)
}

/// Drops `value` without recursing, however deep it nests.
fn dispose(value: Value) {
    let mut stack = vec![value];
    while let Some(v) = stack.pop() {
        match v {
            Value::Array(items) => stack.extend(items),
            Value::Table(entries) => stack.extend(entries.into_iter().map(|(_, v)| v)),
            _ => {}
        }
    }
}

/// The numbers written by [`numbers`], parsed, in order.
fn parse_numbers(text: &str) -> std::vec::IntoIter<DeValue<'_>> {
    let items: Vec<DeValue<'_>> = if text.len() <= 2 {
        Vec::new()
    } else {
        match DeValue::parse(text).map(Spanned::into_inner) {
            Ok(DeValue::Array(mut array)) => array
                .iter_mut()
                .map(|v| std::mem::replace(v.get_mut(), DeValue::Boolean(false)))
                .collect(),
            _ => Vec::new(),
        }
    };
    items.into_iter()
}

/// The key path of `node`: `objects[3].radius`, `materials."a.b".ior`.
fn path_of(nodes: &[(u32, Step)], keys: &[String], node: usize) -> String {
    let mut steps = Vec::new();
    let mut n = node.min(nodes.len().saturating_sub(1));
    while n != 0 {
        let (parent, step) = nodes[n];
        steps.push(step);
        n = parent as usize;
    }
    let mut path = String::new();
    for step in steps.into_iter().rev() {
        match step {
            Step::Index(i) => path.push_str(&format!("[{i}]")),
            Step::Key(k) => {
                if !path.is_empty() {
                    path.push('.');
                }
                let key = &keys[k as usize];
                if !key.is_empty()
                    && key
                        .chars()
                        .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
                {
                    path.push_str(key);
                } else {
                    // Quoted as a TOML key would be, controls escaped.
                    path.push_str(&format!("{key:?}"));
                }
            }
        }
    }
    path
}

/// The builder's messages about an object begin `objects[N]: `; the key
/// path says that already (and N counts only the objects that were read).
fn strip_label(key_path: &str, message: String) -> String {
    if key_path.starts_with("objects[")
        && message.starts_with("objects[")
        && let Some(end) = message.find("]: ")
    {
        return message[end + 3..].to_string();
    }
    message
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(entries: &[(&str, Value)]) -> Value {
        Value::Table(
            entries
                .iter()
                .map(|(k, v)| (k.to_string(), v.clone()))
                .collect(),
        )
    }

    fn v3(a: f64, b: f64, c: f64) -> Value {
        Value::Array(vec![
            Value::Float(a),
            Value::Float(b),
            Value::Integer(c as i64),
        ])
    }

    fn scene(radius: Value, material: &str) -> DictScene {
        let mut d = DictScene::new();
        d.section(
            "camera",
            t(&[
                ("position", v3(0.0, 0.0, 5.0)),
                ("look_at", v3(0.0, 0.0, 0.0)),
            ]),
        );
        d.section(
            "materials",
            t(&[("a.b", t(&[("color", v3(0.8, 0.1, 0.0))]))]),
        );
        d.object(t(&[
            ("type", Value::String("sphere".into())),
            ("center", v3(0.0, 0.0, 0.0)),
            ("radius", Value::Float(1.0)),
            ("material", Value::String("a.b".into())),
        ]));
        d.object(t(&[
            ("type", Value::String("sphere".into())),
            ("center", v3(1.5, -0.25, 0.0)),
            ("radius", radius),
            ("material", Value::String(material.into())),
        ]));
        d
    }

    #[test]
    fn a_dict_scene_is_the_scene_of_the_same_text() {
        let built = scene(Value::Integer(2), "a.b")
            .finish(Path::new("."), &LoadOptions::default())
            .unwrap();
        let text = "[camera]\nposition = [0.0, 0.0, 5]\nlook_at = [0.0, 0.0, 0]\n\
                    [materials.\"a.b\"]\ncolor = [0.8, 0.1, 0]\n\
                    [[objects]]\ntype = \"sphere\"\ncenter = [0.0, 0.0, 0]\nradius = 1.0\nmaterial = \"a.b\"\n\
                    [[objects]]\ntype = \"sphere\"\ncenter = [1.5, -0.25, 0]\nradius = 2\nmaterial = \"a.b\"\n";
        let parsed = Scene::from_toml(text, "t").unwrap();
        assert_eq!(built.aggregate.primitives(), parsed.aggregate.primitives());
        assert_eq!(built.materials, parsed.materials);
        assert_eq!(built.names, parsed.names);
        assert!(!built.inventory.content_hash.is_empty());
    }

    #[test]
    fn problems_name_their_key_path() {
        let problems = scene(Value::Float(-1.0), "a.b")
            .finish(Path::new("."), &LoadOptions::default())
            .unwrap_err();
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert_eq!(problems[0].key_path, "objects[1].radius");
        assert!(problems[0].message.contains("radius"), "{problems:?}");
        assert!(!problems[0].message.starts_with("objects["), "{problems:?}");
        let problems = scene(Value::String("big".into()), "nope\u{1b}[2J")
            .finish(Path::new("."), &LoadOptions::default())
            .unwrap_err();
        let paths: Vec<_> = problems.iter().map(|p| p.key_path.as_str()).collect();
        assert_eq!(paths, ["objects[1].radius"], "{problems:?}");
        let mut d = scene(Value::Float(1.0), "nope");
        d.section("materials", Value::Integer(3));
        d.section("lightz\n", t(&[]));
        let problems = d
            .finish(Path::new("."), &LoadOptions::default())
            .unwrap_err();
        let shown: Vec<_> = problems
            .iter()
            .map(|p| format!("{}: {}", p.key_path, p.message))
            .collect();
        assert!(
            shown.iter().any(|s| s.starts_with("objects[1].material: ")),
            "{shown:?}"
        );
        assert!(
            shown.iter().any(|s| s.starts_with("materials: ")),
            "{shown:?}"
        );
        assert!(
            shown
                .iter()
                .any(|s| s.starts_with("\"lightz\\n\": unknown section `lightz\\n`")),
            "{shown:?}"
        );
        assert!(!shown.iter().any(|s| s.contains('\n')), "{shown:?}");
    }

    fn s(text: &str) -> Value {
        Value::String(text.into())
    }

    /// A CSG `depth` operations deep around a sphere at the origin whose
    /// transform is keyed (the deepest values an object holds), built
    /// without cloning (a clone recurses).
    fn nested_csg(depth: usize) -> Value {
        let key = |frame: i64| {
            Value::Table(vec![
                ("frame".into(), Value::Integer(frame)),
                ("value".into(), v3(0.0, 0.0, 0.0)),
            ])
        };
        let mut v = Value::Table(vec![
            ("type".into(), s("sphere")),
            ("center".into(), v3(0.0, 0.0, 0.0)),
            (
                "transform".into(),
                Value::Array(vec![Value::Table(vec![(
                    "translate".into(),
                    Value::Array(vec![key(0), key(1)]),
                )])]),
            ),
        ]);
        for _ in 0..depth {
            v = Value::Table(vec![
                ("type".into(), s("intersection")),
                ("material".into(), s("a.b")),
                ("children".into(), Value::Array(vec![v])),
            ]);
        }
        v
    }

    fn with_object(object: Value) -> Result<Scene, Vec<Problem>> {
        let mut d = scene(Value::Float(1.0), "a.b");
        d.object(object);
        d.finish(Path::new("."), &LoadOptions::default())
    }

    #[test]
    fn csg_as_deep_as_the_limit_is_read_from_data() {
        // 64 operations (and a keyed transform at the bottom) pass the
        // nesting bound; 65 to 69 reach the builder, which names its limit;
        // past that the values are refused before they are walked.
        assert!(with_object(nested_csg(MAX_CSG_DEPTH)).is_ok());
        for depth in [MAX_CSG_DEPTH + 1, (MAX_NESTING - 6) / 2] {
            let problems = with_object(nested_csg(depth)).unwrap_err();
            assert_eq!(problems.len(), 1, "{problems:?}");
            assert!(
                problems[0].message.contains("CSG nested more than 64 deep"),
                "{problems:?}"
            );
        }
        let problems = with_object(nested_csg(MAX_NESTING / 2)).unwrap_err();
        assert!(
            problems[0].message.contains("nested more than"),
            "{problems:?}"
        );
    }

    #[test]
    fn values_nested_past_the_bound_are_refused_by_key_path() {
        let levels = 100_000;
        // A merge in a merge in a merge …
        let mut deep = t(&[("type", s("sphere"))]);
        for _ in 0..levels {
            deep = Value::Table(vec![
                ("type".into(), s("merge")),
                ("children".into(), Value::Array(vec![deep])),
            ]);
        }
        // A list in a list in a list …
        let mut list = Value::Float(1.0);
        for _ in 0..levels {
            list = Value::Array(vec![list]);
        }
        let mut d = scene(Value::Float(1.0), "a.b");
        d.object(deep);
        d.section("camera", Value::Table(vec![("position".into(), list)]));
        let problems = d
            .finish(Path::new("."), &LoadOptions::default())
            .unwrap_err();
        let limit = format!("nested more than {MAX_NESTING} deep");
        // The first table or list past the bound (level MAX_NESTING + 1):
        // the object's k-th part is level 2k + 1, `position` level 2.
        let object = format!("objects[2]{}", ".children[0]".repeat(MAX_NESTING / 2));
        let camera = format!("camera.position{}", "[0]".repeat(MAX_NESTING - 1));
        let paths: Vec<_> = problems.iter().map(|p| p.key_path.as_str()).collect();
        assert_eq!(paths, [object.as_str(), camera.as_str()], "{problems:?}");
        assert!(
            problems.iter().all(|p| p.message.contains(&limit)),
            "{problems:?}"
        );
    }

    #[test]
    fn numbers_read_back_exactly() {
        for f in [0.1, -0.0, 1e-300, 5e-324, 1.7976931348623157e308, 1e16, 3.0] {
            let (text, _) = numbers(&Value::Float(f), String::new());
            let mut parsed = parse_numbers(&text);
            let back: f64 = serde::Deserialize::deserialize(ValueDeserializer::from(Spanned::new(
                0..1,
                parsed.next().unwrap(),
            )))
            .unwrap();
            assert_eq!(back.to_bits(), f.to_bits(), "{text}");
        }
    }
}
