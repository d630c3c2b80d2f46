//! Stäubli VAL3 applications, as Stäubli Robotics Suite (SRS) and the controller save them
//! and offline tools write them.
//!
//! An application is a folder: `<app>.pjx` (the project: its programs and its data file),
//! `<app>.dtx` (the data, XML) and one `.pgx` per program (XML, the code in a CDATA
//! section). The targets are the `pointRx` and `jointRx` values of the `.dtx`:
//!
//! ```text
//! <Data name="pPart" access="public" xsi:type="array" type="pointRx" size="2">
//!   <Value key="0" x="412.5" y="-80" z="25" ry="90" shoulder="lefty" fatherId="fPart[0]" />
//!   <Value key="1" x="512.5" y="-80" z="25" ry="90" fatherId="fPart[0]" />
//! </Data>
//! ```
//!
//! x, y, z (mm) and rx, ry, rz (degrees, about x, then the new y, then the new z:
//! `R = Rx(rx)·Ry(ry)·Rz(rz)`) of the TCP of the motion's tool in the point's frame,
//! `fatherId`, which chains through the file's `frame` data to `world[0]` (taken as the
//! robot's base frame). SRS omits an attribute whose value is 0: its number is read as 0
//! with an empty span where the attribute goes, and a correction inserts it
//! (` z="1.25"`), every other byte kept.
//!
//! The code tells which values are motion targets: `movej(p, tTool, mDesc)`,
//! `movel(…)` and `movec(pVia, pEnd, tTool, mDesc)` move the TCP of the tool (a `tool`
//! data chained to `flange[0]`) to a point; `movej` to a `jointRx` moves the joints.
//! `appro(p, trsf)` and `compose(p, frame, trsf)` are offsets computed as the program runs
//! (`relative`); any other expression, a local variable or a parameter (which hides data
//! of its name) is `dynamic`, and so is each call handing values to a program that moves
//! to its parameters or locals; a name the data does not hold is `not_declared`; a point
//! assigned by the code (`pPart[0] = here(tGripper, world)`) is `dynamic`; a frame or
//! point the code sets or links (`link(fPart, fCell)`) is `frame_unknown`; a point no
//! motion moves to is left as written (`not_moved`), with where the code uses it. The
//! older format of SRS 6 (`<project>`, `<dataList>`, `<programList>`) is refused by name.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::frames::rotation_from_xyz_intrinsic_deg;
use crate::number::{parse_number, Number, NumberStyle};
use crate::program::{
    AngleUnit, CartesianTarget, ConfigHint, Format, FrameUse, JointTarget, LengthUnit, Orientation,
    Program, ProgramTarget, Reason, Refusal, TargetKind, Undeclared,
};
use crate::source::Source;
use crate::Error;

/// The most bytes a project or program file may have: read whole.
const MAX_FILE_BYTES: u64 = 1 << 28;
/// The most programs an application may list.
const MAX_PROGRAMS: usize = 4096;
/// The deepest XML nesting read, and the longest frame or tool chain.
const MAX_DEPTH: usize = 64;

/// The names of a Cartesian value's numbers, in the order [`Orientation::XyzIntrinsicDeg`]
/// and the position take them.
pub const CARTESIAN: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];

/// The files of a VAL3 application.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Application {
    /// The project, when there is one.
    pub project: Option<PathBuf>,
    /// The data file, whose values are corrected.
    pub data: PathBuf,
    /// The programs, whose code tells which values are motion targets.
    pub programs: Vec<PathBuf>,
}

fn read_bounded(path: &Path) -> Result<Vec<u8>, Error> {
    let size = std::fs::metadata(path)
        .map_err(|source| Error::Read {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    if size > MAX_FILE_BYTES {
        return Err(Error::Option(format!(
            "{}: {size} bytes, more than the {MAX_FILE_BYTES} a VAL3 project or program may have",
            path.display()
        )));
    }
    adwi_runtime::input::read_regular(path).map_err(|source| Error::Read {
        path: path.to_path_buf(),
        source,
    })
}

fn has_extension(path: &Path, ext: &str) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case(ext))
}

impl Application {
    /// The application of `path`: its `.pjx` (the data and programs it lists, beside it),
    /// its folder (which holds one `.pjx`), or its `.dtx` (with the `.pjx` of the same name
    /// beside it, else every `.pgx` of its folder).
    ///
    /// # Errors
    ///
    /// An unreadable or malformed project, a folder without one `.pjx`, a project that
    /// lists no data file or more than one.
    pub fn locate(path: &Path) -> Result<Application, Error> {
        let folder = |p: &Path| p.parent().map_or_else(PathBuf::new, Path::to_path_buf);
        let listing = |dir: &Path, ext: &str| -> Result<Vec<PathBuf>, Error> {
            let entries = std::fs::read_dir(dir).map_err(|source| Error::Read {
                path: dir.to_path_buf(),
                source,
            })?;
            let mut found: Vec<PathBuf> = entries
                .filter_map(Result::ok)
                .map(|e| e.path())
                .filter(|p| p.is_file() && has_extension(p, ext))
                .collect();
            found.sort();
            Ok(found)
        };
        if path.is_dir() {
            let projects = listing(path, "pjx")?;
            return match projects.as_slice() {
                [one] => Application::from_project(one),
                _ => Err(Error::Option(format!(
                    "{}: a VAL3 application's folder holds one .pjx project, this one {}",
                    path.display(),
                    projects.len()
                ))),
            };
        }
        if has_extension(path, "dtx") {
            let project = path.with_extension("pjx");
            if project.is_file() {
                let app = Application::from_project(&project)?;
                if app.data.file_name() == path.file_name() {
                    return Ok(app);
                }
            }
            let programs = listing(&folder(path), "pgx")?;
            return Ok(Application {
                project: None,
                data: path.to_path_buf(),
                programs,
            });
        }
        Application::from_project(path)
    }

    fn from_project(path: &Path) -> Result<Application, Error> {
        let bytes = read_bounded(path)?;
        let name = path.display().to_string();
        let src = Source::new(&name, &bytes);
        let dir = path.parent().map_or_else(PathBuf::new, Path::to_path_buf);
        let mut data: Vec<(usize, PathBuf)> = Vec::new();
        let mut programs = Vec::new();
        let mut saw_project = false;
        let mut old_project: Option<String> = None;
        let mut xml = Xml::new(&src);
        while let Some(tag) = xml.next()? {
            if tag.closing {
                continue;
            }
            let file = tag.attribute(&src, b"file");
            match tag.local_name(&bytes) {
                b"Project" => saw_project = true,
                b"project" => old_project = Some(String::new()),
                b"parameters" if old_project.is_some() => {
                    old_project = tag.attribute(&src, b"version").map(|v| v.1);
                }
                b"Program" => {
                    let (at, file) =
                        file.ok_or_else(|| src.error(tag.start, "a <Program> without its file"))?;
                    if programs.len() == MAX_PROGRAMS {
                        return Err(src.error(at, format!("more than {MAX_PROGRAMS} programs")));
                    }
                    programs.push(dir.join(relative(&src, at, &file)?));
                }
                b"Data" => {
                    let (at, file) =
                        file.ok_or_else(|| src.error(tag.start, "a <Data> without its file"))?;
                    data.push((at, dir.join(relative(&src, at, &file)?)));
                }
                _ => {}
            }
        }
        if !saw_project {
            if let Some(version) = old_project {
                return Err(src.error(0, older_format("project", "<project>", &version)));
            }
            return Err(src.error(0, "not a VAL3 project: no <Project> element"));
        }
        match data.as_slice() {
            [(_, one)] => Ok(Application {
                project: Some(path.to_path_buf()),
                data: one.clone(),
                programs,
            }),
            [] => Err(src.error(0, "the project lists no data file (<Data file=\"….dtx\"/>)")),
            [_, (at, _), ..] => Err(src.error(
                *at,
                "the project lists more than one data file: compensate each as its own .dtx",
            )),
        }
    }

    /// Every file the application's job reads: the project, the data and the programs.
    pub fn files(&self) -> Vec<&Path> {
        let mut files: Vec<&Path> = self.project.iter().map(PathBuf::as_path).collect();
        files.push(&self.data);
        files.extend(self.programs.iter().map(PathBuf::as_path));
        files
    }

    /// The programs' names (as the paths display) and bytes, each bounded.
    ///
    /// # Errors
    ///
    /// A program that cannot be read or is too large.
    pub fn read_programs(&self) -> Result<Vec<(String, Vec<u8>)>, Error> {
        self.programs
            .iter()
            .map(|p| Ok((p.display().to_string(), read_bounded(p)?)))
            .collect()
    }
}

/// A project's file name, refused when it leaves the application's folder.
fn relative(src: &Source, at: usize, file: &str) -> Result<PathBuf, Error> {
    let path = PathBuf::from(file.replace('\\', "/"));
    let plain = path
        .components()
        .all(|c| matches!(c, std::path::Component::Normal(_)));
    if !plain || file.is_empty() {
        return Err(src.error(
            at,
            format!("'{file}': a program or data file of the project is named within its folder"),
        ));
    }
    Ok(path)
}

/// One XML tag: where it is, its name and attributes (spans of their names and values).
struct Tag {
    start: usize,
    /// The byte after the tag's name (where an attribute is inserted when none precedes).
    name_end: usize,
    name: (usize, usize),
    attributes: Vec<Attribute>,
    closing: bool,
    empty: bool,
}

struct Attribute {
    name: (usize, usize),
    /// The value, within the quotes.
    value: (usize, usize),
}

impl Tag {
    fn local_name<'b>(&self, bytes: &'b [u8]) -> &'b [u8] {
        let name = &bytes[self.name.0..self.name.1];
        match name.iter().rposition(|b| *b == b':') {
            Some(p) => &name[p + 1..],
            None => name,
        }
    }

    fn find(&self, bytes: &[u8], name: &[u8]) -> Option<&Attribute> {
        self.attributes
            .iter()
            .find(|a| &bytes[a.name.0..a.name.1] == name)
    }

    /// An attribute's value's offset and text.
    fn attribute(&self, src: &Source, name: &[u8]) -> Option<(usize, String)> {
        self.find(src.bytes, name)
            .map(|a| (a.value.0, src.text(a.value.0, a.value.1)))
    }
}

/// A minimal reader of the tags of an XML file: comments, processing instructions,
/// declarations and CDATA sections skipped (a CDATA section's span kept for the code).
struct Xml<'s, 'a> {
    src: &'s Source<'a>,
    at: usize,
    /// The CDATA sections passed, their contents' spans.
    cdata: Vec<(usize, usize)>,
}

impl<'s, 'a> Xml<'s, 'a> {
    fn new(src: &'s Source<'a>) -> Xml<'s, 'a> {
        let at = if src.bytes.starts_with(b"\xef\xbb\xbf") {
            3
        } else {
            0
        };
        Xml {
            src,
            at,
            cdata: Vec::new(),
        }
    }

    fn find(&self, from: usize, what: &[u8]) -> Option<usize> {
        self.src.bytes[from.min(self.src.bytes.len())..]
            .windows(what.len())
            .position(|w| w == what)
            .map(|p| from + p)
    }

    fn next(&mut self) -> Result<Option<Tag>, Error> {
        let bytes = self.src.bytes;
        loop {
            let Some(open) = bytes[self.at..].iter().position(|b| *b == b'<') else {
                return Ok(None);
            };
            let start = self.at + open;
            let rest = &bytes[start..];
            let skip = |this: &mut Self, end: &[u8], what: &str| -> Result<(), Error> {
                match this.find(start + 2, end) {
                    Some(e) => {
                        this.at = e + end.len();
                        Ok(())
                    }
                    None => Err(this.src.error(
                        start,
                        format!(
                            "{what} not closed ('{}' missing)",
                            String::from_utf8_lossy(end)
                        ),
                    )),
                }
            };
            if rest.starts_with(b"<!--") {
                skip(self, b"-->", "a comment")?;
                continue;
            }
            if rest.starts_with(b"<![CDATA[") {
                let from = start + 9;
                skip(self, b"]]>", "a CDATA section")?;
                self.cdata.push((from, self.at - 3));
                continue;
            }
            if rest.starts_with(b"<?") {
                skip(self, b"?>", "a processing instruction")?;
                continue;
            }
            if rest.starts_with(b"<!") {
                skip(self, b">", "a declaration")?;
                continue;
            }
            return self.tag(start).map(Some);
        }
    }

    fn tag(&mut self, start: usize) -> Result<Tag, Error> {
        let src = self.src;
        let bytes = src.bytes;
        let mut i = start + 1;
        let closing = bytes.get(i) == Some(&b'/');
        if closing {
            i += 1;
        }
        let name_start = i;
        while i < bytes.len() && is_name_byte(bytes[i]) {
            i += 1;
        }
        if i == name_start {
            return Err(src.error(
                start,
                format!(
                    "expected an element's name after '<', found {}",
                    src.describe(i)
                ),
            ));
        }
        let name = (name_start, i);
        let name_end = i;
        let mut attributes = Vec::new();
        loop {
            while i < bytes.len() && bytes[i].is_ascii_whitespace() {
                i += 1;
            }
            match bytes.get(i) {
                None => {
                    return Err(src.error(
                        start,
                        "an element not closed ('>' missing): the file ends inside it",
                    ))
                }
                Some(b'>') => {
                    self.at = i + 1;
                    return Ok(Tag {
                        start,
                        name_end,
                        name,
                        attributes,
                        closing,
                        empty: false,
                    });
                }
                Some(b'/') if bytes.get(i + 1) == Some(&b'>') && !closing => {
                    self.at = i + 2;
                    return Ok(Tag {
                        start,
                        name_end,
                        name,
                        attributes,
                        closing,
                        empty: true,
                    });
                }
                Some(_) if closing => {
                    return Err(src.error(
                        i,
                        format!(
                            "expected '>' closing the element, found {}",
                            src.describe(i)
                        ),
                    ))
                }
                Some(_) => {}
            }
            let attribute_start = i;
            while i < bytes.len() && is_name_byte(bytes[i]) {
                i += 1;
            }
            if i == attribute_start {
                return Err(src.error(
                    i,
                    format!(
                        "expected an attribute, '>' or '/>', found {}",
                        src.describe(i)
                    ),
                ));
            }
            let attribute_name = (attribute_start, i);
            while i < bytes.len() && bytes[i].is_ascii_whitespace() {
                i += 1;
            }
            if bytes.get(i) != Some(&b'=') {
                return Err(src.error(
                    i,
                    format!(
                        "expected '=' after the attribute {}, found {}",
                        src.text(attribute_start, attribute_name.1),
                        src.describe(i)
                    ),
                ));
            }
            i += 1;
            while i < bytes.len() && bytes[i].is_ascii_whitespace() {
                i += 1;
            }
            let quote = match bytes.get(i) {
                Some(q @ (b'"' | b'\'')) => *q,
                _ => {
                    return Err(src.error(
                        i,
                        format!("expected a quoted value, found {}", src.describe(i)),
                    ))
                }
            };
            let value_start = i + 1;
            let Some(len) = bytes[value_start..].iter().position(|b| *b == quote) else {
                return Err(src.error(
                    i,
                    "an attribute's value not closed: the file ends inside it",
                ));
            };
            let value = (value_start, value_start + len);
            if attributes.iter().any(|a: &Attribute| {
                bytes[a.name.0..a.name.1] == bytes[attribute_name.0..attribute_name.1]
            }) {
                return Err(src.error(
                    attribute_start,
                    format!(
                        "the attribute {} twice",
                        src.text(attribute_name.0, attribute_name.1)
                    ),
                ));
            }
            attributes.push(Attribute {
                name: attribute_name,
                value,
            });
            i = value.1 + 1;
        }
    }
}

fn is_name_byte(b: u8) -> bool {
    b.is_ascii_alphanumeric() || matches!(b, b'_' | b':' | b'-' | b'.') || b >= 0x80
}

/// What a `Data` holds, of the types this reader reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Point,
    Joint,
    Frame,
    Tool,
    Other,
}

/// One value of a `pointRx`, `jointRx`, `frame` or `tool` data.
struct Value {
    key: String,
    /// The `<Value` tag's first byte.
    offset: usize,
    numbers: Vec<Number>,
    /// `fatherId`'s text and offset.
    father: Option<(String, usize)>,
    /// A point's configuration.
    config: ConfigHint,
}

/// A `Data` of the file.
struct Data {
    name: String,
    kind: Kind,
    type_name: String,
    offset: usize,
    values: Vec<Value>,
    /// The values' indices by key.
    keys: HashMap<String, usize>,
}

/// The data of the file, and their index by name.
struct Datas {
    list: Vec<Data>,
    names: HashMap<String, usize>,
}

impl std::ops::Deref for Datas {
    type Target = [Data];
    fn deref(&self) -> &[Data] {
        &self.list
    }
}

impl Datas {
    fn index(&self, name: &str) -> Option<usize> {
        self.names.get(name).copied()
    }

    fn get(&self, name: &str) -> Option<&Data> {
        self.index(name).map(|i| &self.list[i])
    }
}

impl Data {
    fn value(&self, key: &str) -> Option<usize> {
        self.keys.get(key).copied()
    }

    /// A frame's or tool's pose in its father.
    fn pose(&self, index: usize) -> Isometry3<f64> {
        let n = &self.values[index].numbers;
        Isometry3::from_parts(
            Translation3::from(Vector3::new(n[0].value, n[1].value, n[2].value)),
            UnitQuaternion::from_rotation_matrix(&rotation_from_xyz_intrinsic_deg([
                n[3].value, n[4].value, n[5].value,
            ])),
        )
    }
}

/// Reads the data file's values.
fn read_data(src: &Source) -> Result<Datas, Error> {
    let bytes = src.bytes;
    let mut xml = Xml::new(src);
    let mut data: Vec<Data> = Vec::new();
    let mut names: HashMap<String, usize> = HashMap::new();
    // The elements open, by name span; the Data open (its index and depth).
    let mut open: Vec<(usize, usize)> = Vec::new();
    let mut in_data: Option<(usize, usize)> = None;
    let mut saw_database = false;
    while let Some(tag) = xml.next()? {
        let local = tag.local_name(bytes);
        if local == b"dataList" && !saw_database {
            return Err(src.error(tag.start, older_format("data file", "<dataList>", "")));
        }
        if tag.closing {
            close(src, &tag, &mut open)?;
            if in_data.is_some_and(|(_, depth)| depth == open.len()) {
                in_data = None;
            }
            continue;
        }
        if local == b"Database" {
            saw_database = true;
        }
        let depth = open.len();
        if !tag.empty {
            if open.len() == MAX_DEPTH {
                return Err(src.error(
                    tag.start,
                    format!("elements nested more than {MAX_DEPTH} deep"),
                ));
            }
            open.push(tag.name);
        }
        if local == b"Data" && in_data.is_none() {
            let d = data_element(src, &tag)?;
            if names.insert(d.name.clone(), data.len()).is_some() {
                let at = tag.attribute(src, b"name").map_or(tag.start, |n| n.0);
                return Err(src.error(at, format!("the data {} twice", d.name)));
            }
            data.push(d);
            if !tag.empty {
                in_data = Some((data.len() - 1, depth));
            }
            continue;
        }
        let Some((index, data_depth)) = in_data else {
            continue;
        };
        if local != b"Value" || depth != data_depth + 1 {
            continue;
        }
        let d = &mut data[index];
        if d.kind == Kind::Other {
            continue;
        }
        let v = value_element(src, &tag, d)?;
        d.keys.insert(v.key.clone(), d.values.len());
        d.values.push(v);
    }
    if let Some(top) = open.last() {
        return Err(src.error(
            top.0,
            format!(
                "<{}> is not closed: the file ends inside it",
                src.text(top.0, top.1)
            ),
        ));
    }
    if !saw_database {
        return Err(src.error(0, "not a VAL3 data file: no <Database> element"));
    }
    Ok(Datas { list: data, names })
}

/// Why a file of the format of Stäubli Robotics Suite 6 (`<project>`, `<dataList>`,
/// `<programList>`, version s6.x) is not read.
fn older_format(what: &str, element: &str, version: &str) -> String {
    let version = if version.is_empty() {
        String::new()
    } else {
        format!(", version {version}")
    };
    format!(
        "a VAL3 {what} in the format of Stäubli Robotics Suite 6 ({element}{version}), which this reader does not read: it reads the format of SRS 7 and later (<Project>, <Database> with <Data> and <Value>, <Programs>)"
    )
}

/// A closing tag checked against the element it closes, which it pops.
fn close(src: &Source, tag: &Tag, open: &mut Vec<(usize, usize)>) -> Result<(), Error> {
    let bytes = src.bytes;
    let Some(top) = open.pop() else {
        return Err(src.error(
            tag.start,
            format!("</{}> closes no element", src.text(tag.name.0, tag.name.1)),
        ));
    };
    if bytes[top.0..top.1] != bytes[tag.name.0..tag.name.1] {
        return Err(src.error(
            tag.start,
            format!(
                "</{}> closes <{}> (line {})",
                src.text(tag.name.0, tag.name.1),
                src.text(top.0, top.1),
                src.location(top.0).0
            ),
        ));
    }
    Ok(())
}

/// A `<Data>` element: its name and type, no values yet.
fn data_element(src: &Source, tag: &Tag) -> Result<Data, Error> {
    let name = tag
        .attribute(src, b"name")
        .ok_or_else(|| src.error(tag.start, "a <Data> without its name"))?;
    let type_name = tag.attribute(src, b"type").map(|t| t.1).unwrap_or_default();
    let kind = match type_name.as_str() {
        "pointRx" => Kind::Point,
        "jointRx" => Kind::Joint,
        "frame" => Kind::Frame,
        "tool" => Kind::Tool,
        _ => Kind::Other,
    };
    Ok(Data {
        name: name.1,
        kind,
        type_name,
        offset: tag.start,
        values: Vec::new(),
        keys: HashMap::new(),
    })
}

/// A `<Value>` of `data` (a `pointRx`, `jointRx`, `frame` or `tool`): its key, which no
/// value before it has, numbers, father and (a point's) configuration.
fn value_element(src: &Source, tag: &Tag, data: &Data) -> Result<Value, Error> {
    let kind = data.kind;
    let key = tag
        .attribute(src, b"key")
        .ok_or_else(|| src.error(tag.start, "a <Value> without its key"))?;
    if data.keys.contains_key(&key.1) {
        return Err(src.error(key.0, format!("the key {} twice in {}", key.1, data.name)));
    }
    let father = tag.attribute(src, b"fatherId").map(|(at, text)| (text, at));
    let config = match kind {
        Kind::Point => val3_config(src, tag),
        _ => ConfigHint::None,
    };
    Ok(Value {
        key: key.1,
        offset: tag.start,
        numbers: value_numbers(src, tag, kind)?,
        father,
        config,
    })
}

/// A value's numbers by their attributes' names (`j1`… for a `jointRx`, [`CARTESIAN`]
/// for the rest); an omitted one is 0 with an empty span where a correction inserts it.
fn value_numbers(src: &Source, tag: &Tag, kind: Kind) -> Result<Vec<Number>, Error> {
    let bytes = src.bytes;
    let names: Vec<String> = match kind {
        Kind::Joint => {
            let mut names: Vec<String> = (1..=6).map(|j| format!("j{j}")).collect();
            // A seventh or further axis, when written.
            for j in 7..=crate::bounds::MAX_JOINTS {
                if tag.find(bytes, format!("j{j}").as_bytes()).is_some() {
                    names.truncate(j - 1);
                    names.extend((names.len() + 1..=j).map(|k| format!("j{k}")));
                }
            }
            names
        }
        _ => CARTESIAN.iter().map(|s| s.to_string()).collect(),
    };
    // An omitted number goes after the last attribute written before it, in the
    // order key, then the numbers; after the element's name when none is.
    let mut after = tag
        .find(bytes, b"key")
        .map_or(tag.name_end, |a| a.value.1 + 1);
    let mut numbers = Vec::with_capacity(names.len());
    for name in &names {
        match tag.find(bytes, name.as_bytes()) {
            Some(a) => {
                let n = parse_number(&bytes[..a.value.1], a.value.0)
                    .filter(|n| n.span.1 == a.value.1)
                    .ok_or_else(|| {
                        src.error(
                            a.value.0,
                            format!(
                                "{name} must be a number, found '{}'",
                                src.text(a.value.0, a.value.1)
                            ),
                        )
                    })?;
                numbers.push(n);
                after = after.max(a.value.1 + 1);
            }
            None => numbers.push(Number {
                span: (after, after),
                value: 0.0,
                style: NumberStyle {
                    decimals: 0,
                    point: false,
                    plus: false,
                    bare_point: false,
                    exponent: None,
                    decimal_comma: false,
                },
            }),
        }
    }
    Ok(numbers)
}

/// A `pointRx` value's `config` (the VAL3 manual's `config` type): `shoulder` `righty` or
/// `lefty`, `elbow` `epositive` or `enegative` (J3 ≥ 0 or not), `wrist` `wpositive` or
/// `wnegative` (J5 ≥ 0 or not); `ssame`/`sfree`, `esame`/`efree`, `wsame`/`wfree`, and an
/// omitted attribute (SRS omits the default, `same`) leave the part to the controller. A
/// value that is none of these is [`ConfigHint::Unreadable`].
fn val3_config(src: &Source, tag: &Tag) -> ConfigHint {
    let part = |name: &[u8], words: [&str; 4], expected: &'static str| {
        let Some(a) = tag.find(src.bytes, name) else {
            return Ok(None);
        };
        match words
            .iter()
            .position(|w| w.as_bytes() == &src.bytes[a.value.0..a.value.1])
        {
            Some(0) => Ok(Some(true)),
            Some(1) => Ok(Some(false)),
            Some(_) => Ok(None),
            None => Err(ConfigHint::Unreadable {
                span: a.value,
                expected,
            }),
        }
    };
    let parts = (
        part(
            b"shoulder",
            ["righty", "lefty", "ssame", "sfree"],
            "shoulder is righty, lefty, ssame or sfree",
        ),
        part(
            b"elbow",
            ["epositive", "enegative", "esame", "efree"],
            "elbow is epositive, enegative, esame or efree",
        ),
        part(
            b"wrist",
            ["wpositive", "wnegative", "wsame", "wfree"],
            "wrist is wpositive, wnegative, wsame or wfree",
        ),
    );
    match parts {
        (Ok(righty), Ok(elbow_positive), Ok(wrist_positive)) => {
            if righty.is_none() && elbow_positive.is_none() && wrist_positive.is_none() {
                ConfigHint::None
            } else {
                ConfigHint::Val3 {
                    righty,
                    elbow_positive,
                    wrist_positive,
                }
            }
        }
        (Err(e), ..) | (_, Err(e), _) | (.., Err(e)) => e,
    }
}

/// A reference to data in the code: its name and key (`None`: an index computed as the
/// program runs, any element).
#[derive(Clone, Debug, PartialEq, Eq)]
struct Reference {
    name: String,
    key: Option<String>,
}

/// Reads a reference that is the whole of `text`: `name`, `name[3]`, `name["a"]`,
/// `name[i]`.
fn reference(text: &str) -> Option<Reference> {
    let text = text.trim();
    let name_end = text
        .bytes()
        .position(|b| !(b.is_ascii_alphanumeric() || b == b'_'))
        .unwrap_or(text.len());
    let name = &text[..name_end];
    if name.is_empty() || name.as_bytes()[0].is_ascii_digit() {
        return None;
    }
    let rest = text[name_end..].trim();
    if rest.is_empty() {
        return Some(Reference {
            name: name.to_string(),
            key: Some("0".into()),
        });
    }
    let index = rest.strip_prefix('[')?.strip_suffix(']')?.trim();
    let key = if !index.is_empty() && index.bytes().all(|b| b.is_ascii_digit()) {
        Some(index.trim_start_matches('0').to_string()).map(|k| {
            if k.is_empty() {
                "0".into()
            } else {
                k
            }
        })
    } else if index.len() >= 2 && index.starts_with('"') && index.ends_with('"') {
        Some(index[1..index.len() - 1].to_string())
    } else {
        None
    };
    Some(Reference {
        name: name.to_string(),
        key,
    })
}

/// A motion's target argument, as this reader takes it.
enum Argument {
    /// A data reference.
    Data(Reference),
    /// An offset from a reference (`appro`, `compose`): the function's name.
    Offset(&'static str, Option<Reference>),
    /// Any other expression.
    Expression,
}

fn argument(text: &str) -> Argument {
    let t = text.trim();
    for f in ["appro", "compose"] {
        if let Some(rest) = t.strip_prefix(f) {
            if let Some(inner) = rest.trim_start().strip_prefix('(') {
                let first = split_arguments(inner.as_bytes(), 0)
                    .and_then(|(args, _)| args.first().map(|(s, e)| inner[*s..*e].to_string()));
                return Argument::Offset(f, first.as_deref().and_then(reference));
            }
        }
    }
    match reference(t) {
        Some(r) => Argument::Data(r),
        None => Argument::Expression,
    }
}

/// The arguments of a call whose `(` is just before `bytes[from]`: their spans (trimmed),
/// and the byte after the closing `)`. `None` when it is not closed.
fn split_arguments(bytes: &[u8], from: usize) -> Option<(Vec<(usize, usize)>, usize)> {
    let mut depth = 0usize;
    let mut args = Vec::new();
    let mut start = from;
    let mut i = from;
    let trimmed = |s: usize, e: usize| {
        let mut s = s;
        let mut e = e;
        while s < e && bytes[s].is_ascii_whitespace() {
            s += 1;
        }
        while e > s && bytes[e - 1].is_ascii_whitespace() {
            e -= 1;
        }
        (s, e)
    };
    while i < bytes.len() {
        match bytes[i] {
            b'"' => {
                i += 1;
                while i < bytes.len() && bytes[i] != b'"' {
                    i += 1;
                }
            }
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b']' | b'}' if depth > 0 => depth -= 1,
            b')' => {
                let last = trimmed(start, i);
                if last.0 < last.1 || !args.is_empty() {
                    args.push(last);
                }
                return Some((args, i + 1));
            }
            b',' if depth == 0 => {
                args.push(trimmed(start, i));
                start = i + 1;
            }
            _ => {}
        }
        i += 1;
    }
    None
}

/// What the code does with the data: the motions and their targets, the data it assigns,
/// and where it names each data otherwise.
#[derive(Default)]
struct Code {
    motions: Vec<Motion>,
    /// Data assigned as the programs run, by name: the key (`None`: any) and the place.
    assigned: HashMap<String, Places>,
    /// The first place the code names each data outside a motion's targets.
    named: std::collections::HashMap<String, String>,
    /// Names local to a program (its locals and parameters), with the program.
    locals: std::collections::HashMap<String, String>,
    /// Each program's locals and parameters: (program, name).
    program_locals: std::collections::HashSet<(String, String)>,
    /// Data whose frame `link(…)` sets as the programs run: the key (`None`: any) and the
    /// place.
    linked: HashMap<String, Places>,
    /// The calls of programs: `call NAME(arguments)`.
    calls: Vec<Call>,
    /// The application's programs' names.
    programs: Vec<String>,
}

impl Code {
    fn assign(&mut self, r: Reference, place: String) {
        self.assigned.entry(r.name).or_default().add(r.key, place);
    }

    /// Where the code first links `name[key]` to a frame, if it does.
    fn linked_at(&self, name: &str, key: &str) -> Option<&str> {
        self.linked.get(name)?.first(key)
    }

    /// Where the code first assigns `name[key]`, if it does.
    fn assigned_at(&self, name: &str, key: &str) -> Option<&str> {
        self.assigned.get(name)?.first(key)
    }
}

/// The places the code does something to one data: to any of its values (a reference
/// without a key, or with one computed as it runs), or to each key; the first of each,
/// in the code's order.
#[derive(Default)]
struct Places {
    count: usize,
    any: Option<(usize, String)>,
    keys: HashMap<String, (usize, String)>,
}

impl Places {
    fn add(&mut self, key: Option<String>, place: String) {
        let n = self.count;
        self.count += 1;
        match key {
            None => {
                self.any.get_or_insert((n, place));
            }
            Some(k) => {
                self.keys.entry(k).or_insert((n, place));
            }
        }
    }

    /// The first place that does it to `key`.
    fn first(&self, key: &str) -> Option<&str> {
        match (&self.any, self.keys.get(key)) {
            (Some(a), Some(k)) => Some(if a.0 < k.0 { &a.1 } else { &k.1 }),
            (Some((_, p)), None) | (None, Some((_, p))) => Some(p),
            (None, None) => None,
        }
        .map(String::as_str)
    }
}

/// A call of a program: `call pick(pPart[2])`.
struct Call {
    program: String,
    place: String,
    /// The call as written (its first 80 characters).
    text: String,
    args: Vec<String>,
}

struct Motion {
    /// `movej`, `movel`, `movec`, or the other motion-looking call.
    instruction: String,
    /// The program it is in.
    program: String,
    place: String,
    /// The call as written, for messages (its first 80 characters).
    text: String,
    /// The targets' arguments' texts; the tool's.
    targets: Vec<String>,
    tool: Option<String>,
    /// Why it is not read as a motion, when it is not.
    unknown: Option<String>,
}

/// The motion instructions this reader corrects, with their target arguments and the
/// argument holding the tool (counted from 0).
pub const MOTIONS: [(&str, &[usize], usize); 3] = [
    ("movej", &[0], 1),
    ("movel", &[0], 1),
    ("movec", &[0, 1], 2),
];

fn read_code(programs: &[Source], code: &mut Code) -> Result<(), Error> {
    for src in programs {
        crate::bounds::check_line_lengths(src)?;
        let bytes = src.bytes;
        let mut xml = Xml::new(src);
        let mut program = String::new();
        let mut starts: Vec<(usize, String)> = Vec::new();
        let mut saw_programs = false;
        while let Some(tag) = xml.next()? {
            if tag.closing {
                continue;
            }
            match tag.local_name(bytes) {
                b"Programs" => saw_programs = true,
                b"programList" if !saw_programs => {
                    return Err(src.error(tag.start, older_format("program", "<programList>", "")));
                }
                b"Program" => {
                    if let Some((_, name)) = tag.attribute(src, b"name") {
                        code.programs.push(name.clone());
                        starts.push((tag.start, name.clone()));
                        program = name;
                    }
                }
                b"Local" | b"Parameter" => {
                    if let Some((_, name)) = tag.attribute(src, b"name") {
                        code.program_locals.insert((program.clone(), name.clone()));
                        code.locals.entry(name).or_insert_with(|| program.clone());
                    }
                }
                _ => {}
            }
        }
        if !saw_programs {
            return Err(src.error(0, "not a VAL3 program: no <Programs> element"));
        }
        for (start, end) in xml.cdata.clone() {
            let k = starts.partition_point(|(at, _)| *at < start);
            let program = k.checked_sub(1).map_or("", |k| starts[k].1.as_str());
            read_statements(src, start, end, code, program);
        }
    }
    Ok(())
}

/// Reads the code between `start` and `end` of `src`: its motions, assignments and names.
fn read_statements(src: &Source, start: usize, end: usize, code: &mut Code, program: &str) {
    let statements = Statements {
        src,
        bytes: &src.bytes[..end],
        program,
    };
    let bytes = statements.bytes;
    let mut i = start;
    // The end of the last motion's arguments: names within them are its targets.
    let mut within_motion = 0;
    let mut previous_word: (usize, usize) = (0, 0);
    while i < end {
        if let Some(after) = skip_comment_or_string(bytes, i) {
            i = after;
            continue;
        }
        let b = bytes[i];
        if !(b.is_ascii_alphabetic() || b == b'_') {
            i += 1;
            continue;
        }
        let word_start = i;
        while i < end && (bytes[i].is_ascii_alphanumeric() || bytes[i] == b'_') {
            i += 1;
        }
        let word = String::from_utf8_lossy(&bytes[word_start..i]).into_owned();
        let after_member = word_start > 0 && bytes[word_start - 1] == b'.';
        let called = bytes[previous_word.0..previous_word.1] == *b"call";
        previous_word = (word_start, i);
        if after_member {
            continue;
        }
        let mut j = i;
        while j < end && matches!(bytes[j], b' ' | b'\t') {
            j += 1;
        }
        let is_call = bytes.get(j) == Some(&b'(');
        // RoboDK's `$Xmovel(…)`: a call of a library's motion, named with its `$`.
        let dollar = word_start > start && bytes[word_start - 1] == b'$';
        let lower = word.to_ascii_lowercase();
        let motion = MOTIONS.iter().find(|m| m.0 == word).filter(|_| !dollar);
        let looks = lower.starts_with("move")
            || word.starts_with("alterMove")
            || (dollar && lower.contains("move"));
        let word = if dollar { format!("${word}") } else { word };
        let word_start = if dollar { word_start - 1 } else { word_start };
        if called && is_call {
            statements.read_call(code, &word, word_start, j + 1);
        }
        if is_call && !called && (motion.is_some() || looks) && !code.programs.contains(&word) {
            if let Some(close) = statements.read_motion(code, &word, word_start, j + 1, motion) {
                within_motion = close;
            }
            // The arguments are read again for the names they hold, which are not targets
            // (the tool, the motion descriptor).
            i = j + 1;
            continue;
        }
        if is_call {
            statements.read_frame_call(code, &word, j + 1);
        }
        if let Some(reference_end) = assigned_reference_end(bytes, j) {
            if let Some(r) = reference(&statements.text(word_start, reference_end)) {
                code.assign(r, statements.place(word_start));
            }
        } else if word_start >= within_motion {
            code.named
                .entry(word)
                .or_insert_with(|| statements.place(word_start));
        }
    }
}

/// The code [`read_statements`] reads, shared by the helpers that read each kind of
/// statement: its bytes, cut at the code's end so no argument list is read past it, and
/// its file and program, for the places and motions they record.
struct Statements<'a> {
    src: &'a Source<'a>,
    bytes: &'a [u8],
    program: &'a str,
}

impl Statements<'_> {
    /// `file:line:column` of the byte `at`: how messages name a place in the code.
    fn place(&self, at: usize) -> String {
        let (line, column) = self.src.location(at);
        format!("{}:{line}:{column}", self.src.name)
    }

    /// The code's text from `start` to `end`, decoded lossily: it is only matched against
    /// ASCII names or shown in messages.
    fn text(&self, start: usize, end: usize) -> String {
        String::from_utf8_lossy(&self.bytes[start..end]).into_owned()
    }

    /// `call NAME(…)` at `word_start`, its `(` just before `from`: kept with its arguments'
    /// texts, since a called program that moves to its parameters moves to what it is handed.
    fn read_call(&self, code: &mut Code, word: &str, word_start: usize, from: usize) {
        let Some((args, close)) = split_arguments(self.bytes, from) else {
            return;
        };
        code.calls.push(Call {
            program: word.to_string(),
            place: self.place(word_start),
            text: format!("call {}", self.text(word_start, close.min(word_start + 80))),
            args: args.iter().map(|(s, e)| self.text(*s, *e)).collect(),
        });
    }

    /// The motion (or motion-looking call) `word` at `word_start`, its `(` just before
    /// `from`: its targets and tool when it is one of [`MOTIONS`] with enough arguments,
    /// else why this reader does not correct it, reported with the motion. The end of its
    /// arguments, `None` when they are not closed (nothing is recorded then).
    fn read_motion(
        &self,
        code: &mut Code,
        word: &str,
        word_start: usize,
        from: usize,
        motion: Option<&(&str, &[usize], usize)>,
    ) -> Option<usize> {
        let (args, close) = split_arguments(self.bytes, from)?;
        let texts: Vec<String> = args.iter().map(|(s, e)| self.text(*s, *e)).collect();
        let mut m = Motion {
            instruction: word.to_string(),
            program: self.program.to_string(),
            place: self.place(word_start),
            text: self.text(word_start, close.min(word_start + 80)),
            targets: Vec::new(),
            tool: None,
            unknown: None,
        };
        match motion {
            Some((_, targets, tool)) if texts.len() > *tool => {
                m.targets = targets.iter().map(|k| texts[*k].clone()).collect();
                m.tool = Some(texts[*tool].clone());
            }
            Some((_, _, tool)) => {
                m.unknown = Some(format!(
                    "{word} with {} arguments: the tool is its argument {}",
                    texts.len(),
                    tool + 1
                ));
            }
            None => {
                m.targets = texts.first().cloned().into_iter().collect();
                m.unknown = Some(format!("{word} is not a VAL3 motion this reader corrects"));
            }
        }
        code.motions.push(m);
        Some(close)
    }

    /// `link(…)` or `setFrame(…)`, its `(` just before `from`: each gives a frame its value
    /// only as the program runs, so the data's own value cannot be trusted for it.
    fn read_frame_call(&self, code: &mut Code, word: &str, from: usize) {
        match word {
            // link(point or frame, frame): its frame set as the program runs.
            "link" => {
                if let Some((r, at)) = self.argument_reference(from, 0) {
                    code.linked
                        .entry(r.name)
                        .or_default()
                        .add(r.key, self.place(at));
                }
            }
            // setFrame(origin, x, xy, frame): the frame computed as the program runs.
            "setFrame" => {
                if let Some((r, at)) = self.argument_reference(from, 3) {
                    code.assign(r, self.place(at));
                }
            }
            _ => {}
        }
    }

    /// The reference that is the whole of argument `k` of the call whose `(` is just before
    /// `from`, and where it starts; `None` when the call is not closed or the argument is
    /// missing or an expression.
    fn argument_reference(&self, from: usize, k: usize) -> Option<(Reference, usize)> {
        let (args, _) = split_arguments(self.bytes, from)?;
        let &(s, e) = args.get(k)?;
        Some((reference(&self.text(s, e))?, s))
    }
}

/// Where the comment or string starting at `i` ends, if one does: the words in them are
/// not code. A string left open ends with its line, so a stray quote hides no more.
fn skip_comment_or_string(bytes: &[u8], mut i: usize) -> Option<usize> {
    if bytes[i] == b'/' && bytes.get(i + 1) == Some(&b'/') {
        while i < bytes.len() && bytes[i] != b'\n' && bytes[i] != b'\r' {
            i += 1;
        }
        return Some(i);
    }
    if bytes[i] == b'"' {
        i += 1;
        while i < bytes.len() && bytes[i] != b'"' && bytes[i] != b'\n' {
            i += 1;
        }
        return Some(i + 1);
    }
    None
}

/// When the word ending at `after_word` is assigned (its index, any fields, then `=`, not
/// `==`): the end of the reference, its index included but not its fields, since setting
/// a field changes the value the reference names.
fn assigned_reference_end(bytes: &[u8], after_word: usize) -> Option<usize> {
    let mut k = after_word;
    if bytes.get(k) == Some(&b'[') {
        let mut depth = 0;
        while k < bytes.len() {
            match bytes[k] {
                b'[' => depth += 1,
                b']' => {
                    depth -= 1;
                    if depth == 0 {
                        k += 1;
                        break;
                    }
                }
                _ => {}
            }
            k += 1;
        }
    }
    let reference_end = k;
    while k < bytes.len()
        && (bytes[k].is_ascii_alphanumeric() || matches!(bytes[k], b'.' | b'_' | b' ' | b'\t'))
    {
        k += 1;
    }
    let assigns = bytes.get(k) == Some(&b'=') && bytes.get(k + 1) != Some(&b'=');
    assigns.then_some(reference_end)
}

/// Reads the targets of a VAL3 application: its data file `src` and its programs.
///
/// # Errors
///
/// [`Error::Syntax`] at the first malformed element of any file.
pub fn read(src: &Source, programs: &[Source]) -> Result<Program, Error> {
    read_at_most(src, programs, usize::MAX)
}

/// A point's or joint value's uses by the code.
#[derive(Default)]
struct Uses {
    frames: Vec<FrameUse>,
    refused: Vec<Refusal>,
    direct: bool,
}

/// [`read`], stopping after `limit` targets ([`Program::truncated_at`]).
///
/// # Errors
///
/// As [`read`].
pub fn read_at_most(src: &Source, programs: &[Source], limit: usize) -> Result<Program, Error> {
    let data = read_data(src)?;
    let mut code = Code::default();
    read_code(programs, &mut code)?;
    let mut walk = MotionWalk::new(&data, &code);
    for m in &code.motions {
        walk.motion(m);
    }
    let MotionWalk {
        mut uses,
        mut refused_motions,
        local_movers,
        ..
    } = walk;
    // The values a call hands to a program that moves to its locals or parameters: not in
    // the data, so not corrected; each call reported.
    for call in &code.calls {
        let Some((motion, at)) = local_movers.get(&call.program) else {
            continue;
        };
        let passes_values = call.args.iter().any(|a| match argument(a) {
            Argument::Data(r) => data.index(&r.name).is_none(),
            _ => true,
        });
        if !passes_values {
            continue;
        }
        refused_motions.push(ProgramTarget {
            name: "call".into(),
            offset: 0,
            kind: TargetKind::Motion,
            uses: Vec::new(),
            refused: Some(Refusal::new(
                Reason::Dynamic,
                format!(
                    "{} at {}: {} moves to what it is handed ({} at {}), values the data does not hold: not corrected",
                    crate::escape_controls(&call.text),
                    call.place,
                    call.program,
                    crate::escape_controls(motion),
                    at
                ),
            )),
        });
    }
    let (mut targets, mut truncated_at) = data_targets(&data, &code, &mut uses, limit);
    if truncated_at.is_none() {
        targets.extend(refused_motions);
        if targets.len() > limit {
            truncated_at = Some(src.bytes.len());
        }
    }
    Ok(Program {
        format: Format::Val3,
        targets,
        truncated_at,
        first_motion: None,
        in_partner: Vec::new(),
    })
}

/// The code's motions walked for the data they move to: each value's uses (its frames,
/// or why not), and the motions refused as a whole.
struct MotionWalk<'d> {
    data: &'d Datas,
    code: &'d Code,
    /// Per data, per value: the uses.
    uses: Vec<Vec<Uses>>,
    refused_motions: Vec<ProgramTarget>,
    /// The programs that move to a local variable or parameter of theirs: the first such
    /// motion and its place.
    local_movers: HashMap<String, (String, String)>,
}

impl<'d> MotionWalk<'d> {
    fn new(data: &'d Datas, code: &'d Code) -> MotionWalk<'d> {
        MotionWalk {
            data,
            code,
            uses: data
                .iter()
                .map(|d| d.values.iter().map(|_| Uses::default()).collect())
                .collect(),
            refused_motions: Vec::new(),
            local_movers: HashMap::new(),
        }
    }

    /// A motion reported as a whole, with what it is and why.
    fn refuse_motion(&mut self, m: &Motion, at: usize, reason: Reason, why: String) {
        self.refused_motions.push(ProgramTarget {
            name: m.instruction.clone(),
            offset: at,
            kind: TargetKind::Motion,
            uses: Vec::new(),
            refused: Some(Refusal::new(
                reason,
                format!("{} at {}: {why}", crate::escape_controls(&m.text), m.place),
            )),
        });
    }

    /// One motion: each target argument's data used in the motion's tool, or the motion
    /// (and what it names) reported.
    fn motion(&mut self, m: &Motion) {
        if let Some(why) = &m.unknown {
            self.unknown_motion(m, why);
            return;
        }
        let tool = m
            .tool
            .as_deref()
            .map(|t| tool_frame(self.data, self.code, t));
        for t in &m.targets {
            self.argument(m, tool.as_ref(), t);
        }
    }

    /// A call that looks like a motion but is not one this reader corrects: reported, and
    /// every value it names refused with it.
    fn unknown_motion(&mut self, m: &Motion, why: &str) {
        let reason = Reason::UnknownMotion;
        self.refuse_motion(m, 0, reason, why.to_string());
        for t in &m.targets {
            let Argument::Data(r) = argument(t) else {
                continue;
            };
            let Some(d) = self.data.index(&r.name) else {
                continue;
            };
            for (k, v) in self.data[d].values.iter().enumerate() {
                if r.key.as_deref().is_none_or(|key| key == v.key) {
                    self.uses[d][k].refused.push(Refusal::new(
                        reason,
                        format!("{} ({}): {why}", m.instruction, m.place),
                    ));
                }
            }
        }
    }

    /// A target argument `t` of motion `m`: the values it moves to directly, each with its
    /// frames in `tool`; an expression, a local, a name the data lacks, data of another
    /// type, a key with no value or an offset reported.
    fn argument(&mut self, m: &Motion, tool: Option<&Result<Isometry3<f64>, Missing>>, t: &str) {
        let (data, code) = (self.data, self.code);
        let (r, offset) = match argument(t) {
            Argument::Data(r) => (r, None),
            Argument::Offset(f, r) => (
                r.unwrap_or(Reference {
                    name: String::new(),
                    key: None,
                }),
                Some(f),
            ),
            Argument::Expression => {
                let why = format!(
                    "'{}' is computed as the program runs",
                    crate::escape_controls(t.trim())
                );
                self.refuse_motion(m, 0, Reason::Dynamic, why);
                return;
            }
        };
        // A local or parameter of the motion's program hides the global of its name.
        let local = code
            .program_locals
            .contains(&(m.program.clone(), r.name.clone()));
        if local || (data.index(&r.name).is_none() && code.locals.contains_key(&r.name)) {
            let program = if local {
                m.program.clone()
            } else {
                code.locals[&r.name].clone()
            };
            self.local_movers
                .entry(program.clone())
                .or_insert_with(|| (m.text.clone(), m.place.clone()));
            let why = format!(
                "{} is a local variable or parameter of {program}, set as the program runs",
                r.name
            );
            self.refuse_motion(m, 0, Reason::Dynamic, why);
            return;
        }
        let Some(d) = data.index(&r.name) else {
            let (reason, why) = match code.locals.get(&r.name) {
                Some(p) => (
                    Reason::Dynamic,
                    format!(
                        "{} is a local variable or parameter of {p}, set as the program runs",
                        r.name
                    ),
                ),
                None if offset.is_some() => (
                    Reason::Relative,
                    format!(
                        "an offset ({}) computed as the program runs",
                        offset.unwrap_or_default()
                    ),
                ),
                None => (
                    Reason::NotDeclared,
                    format!("{} is not in the application's data", r.name),
                ),
            };
            self.refuse_motion(m, 0, reason, why);
            return;
        };
        let item = &data[d];
        if !matches!(item.kind, Kind::Point | Kind::Joint) {
            let why = format!(
                "{} is a {}, not a pointRx or jointRx",
                r.name, item.type_name
            );
            self.refuse_motion(m, item.offset, Reason::Dynamic, why);
            return;
        }
        let keys: Vec<usize> = match &r.key {
            Some(key) => match item.value(key) {
                Some(k) => vec![k],
                None => {
                    let why = format!("{}[{key}] has no value in the data", r.name);
                    self.refuse_motion(m, item.offset, Reason::NotDeclared, why);
                    return;
                }
            },
            None => (0..item.values.len()).collect(),
        };
        if let Some(f) = offset {
            let why = format!("{f}(…): an offset computed as the program runs");
            self.refuse_motion(m, item.offset, Reason::Relative, why.clone());
            for k in keys {
                self.uses[d][k].refused.push(Refusal::new(
                    Reason::Relative,
                    format!("{} ({}): {why}", m.text, m.place),
                ));
            }
            return;
        }
        for k in keys {
            let u = &mut self.uses[d][k];
            u.direct = true;
            if item.kind == Kind::Point {
                let frame = point_frames(data, code, &item.name, &item.values[k], m, tool);
                if !u.frames.contains(&frame) {
                    u.frames.push(frame);
                }
            }
        }
    }
}

/// A point's frames as motion `m` moves to it: the motion's tool, and the point's father
/// chained to the world; or what is not known of them.
fn point_frames(
    data: &Datas,
    code: &Code,
    name: &str,
    value: &Value,
    m: &Motion,
    tool: Option<&Result<Isometry3<f64>, Missing>>,
) -> FrameUse {
    let mut frame = FrameUse {
        tool: None,
        base: None,
        offset: value.offset,
        elsewhere: Some(m.place.clone()),
        note: None,
        undeclared: Vec::new(),
        unknown: Vec::new(),
    };
    match tool {
        Some(Ok(t)) => frame.tool = Some(*t),
        Some(Err(Missing::Undeclared(name))) => frame.undeclared.push(Undeclared {
            base: false,
            name: name.clone(),
        }),
        Some(Err(Missing::Unknown(why))) => frame.unknown.push(why.clone()),
        None => {}
    }
    if let Some(at) = code.linked_at(name, &value.key) {
        frame.unknown.push(format!(
            "{name}[{}] is linked to a frame as the program runs ({at})",
            value.key
        ));
    }
    match father_frame(data, code, value.father.as_ref().map(|f| f.0.as_str()), 0) {
        Ok(b) => frame.base = Some(b),
        Err(Missing::Undeclared(name)) => frame.undeclared.push(Undeclared { base: true, name }),
        Err(Missing::Unknown(why)) => frame.unknown.push(why),
    }
    frame
}

/// The data's points and joint values as targets, in the file's order, each with its uses
/// (at most `limit`: then where reading stopped).
fn data_targets(
    data: &Datas,
    code: &Code,
    uses: &mut [Vec<Uses>],
    limit: usize,
) -> (Vec<ProgramTarget>, Option<usize>) {
    let mut targets: Vec<ProgramTarget> = Vec::new();
    for (d, item) in data.iter().enumerate() {
        if !matches!(item.kind, Kind::Point | Kind::Joint) {
            continue;
        }
        for (k, v) in item.values.iter().enumerate() {
            if targets.len() >= limit {
                return (targets, Some(v.offset));
            }
            let u = std::mem::take(&mut uses[d][k]);
            let kind = match item.kind {
                Kind::Point => TargetKind::Cartesian(Box::new(CartesianTarget {
                    position: [v.numbers[0], v.numbers[1], v.numbers[2]],
                    unit: LengthUnit::Millimetre,
                    orientation: Some(Orientation::XyzIntrinsicDeg([
                        v.numbers[3],
                        v.numbers[4],
                        v.numbers[5],
                    ])),
                    config: v.config,
                    joints: Vec::new(),
                })),
                _ => TargetKind::Joints(JointTarget {
                    joints: v.numbers.clone(),
                    unit: AngleUnit::Degree,
                }),
            };
            targets.push(ProgramTarget {
                name: format!("{}[{}]", item.name, v.key),
                offset: v.offset,
                kind,
                refused: value_refusal(code, item, v, &u),
                uses: u.frames,
            });
        }
    }
    (targets, None)
}

/// Why a value is left as written: assigned by the code although moved to, moved to only
/// through refused uses (the first named), or moved to by no motion; `None` when moved to.
fn value_refusal(code: &Code, item: &Data, v: &Value, u: &Uses) -> Option<Refusal> {
    if let (true, Some(at)) = (u.direct, code.assigned_at(&item.name, &v.key)) {
        Some(Refusal::new(
            Reason::Dynamic,
            format!("assigned as the program runs ({at})"),
        ))
    } else if u.direct {
        None
    } else if let Some(r) = u.refused.first() {
        Some(Refusal::new(
            r.reason,
            format!("moved to only as {}", r.detail),
        ))
    } else {
        Some(Refusal::new(
            Reason::NotMoved,
            match code.named.get(&item.name) {
                Some(at) => {
                    format!("no motion moves to it; the code uses it otherwise (first at {at})")
                }
                None => "no motion moves to it, and no program names it".to_string(),
            },
        ))
    }
}

/// Why a frame or tool is not known.
enum Missing {
    /// Named, but not in the data: the job's options may stand for it.
    Undeclared(String),
    /// Known only as the program runs, or not a frame.
    Unknown(String),
}

/// Splits `name[key]` (a `fatherId`).
fn father_reference(text: &str) -> Option<Reference> {
    reference(text)
}

/// The frame a `fatherId` names, in the world frame.
fn father_frame(
    data: &Datas,
    code: &Code,
    father: Option<&str>,
    depth: usize,
) -> Result<Isometry3<f64>, Missing> {
    let Some(father) = father.map(str::trim).filter(|f| !f.is_empty()) else {
        return Ok(Isometry3::identity());
    };
    let Some(r) = father_reference(father) else {
        return Err(Missing::Unknown(format!(
            "fatherId '{}' is not a frame's name",
            crate::escape_controls(father)
        )));
    };
    if r.name == "world" {
        return Ok(Isometry3::identity());
    }
    if depth >= MAX_DEPTH {
        return Err(Missing::Unknown(format!(
            "the frame chain through {father} is more than {MAX_DEPTH} deep (a cycle)"
        )));
    }
    let Some(d) = data.get(&r.name) else {
        return Err(Missing::Undeclared(father.to_string()));
    };
    if d.kind != Kind::Frame {
        return Err(Missing::Unknown(format!(
            "fatherId {father} is a {}, not a frame",
            d.type_name
        )));
    }
    let key = r.key.unwrap_or_default();
    let Some(k) = d.value(&key) else {
        return Err(Missing::Undeclared(father.to_string()));
    };
    if let Some(at) = code.assigned_at(&d.name, &key) {
        return Err(Missing::Unknown(format!(
            "frame {father} is set as the program runs ({at})"
        )));
    }
    if let Some(at) = code.linked_at(&d.name, &key) {
        return Err(Missing::Unknown(format!(
            "frame {father} is linked to another frame as the program runs ({at})"
        )));
    }
    let up = father_frame(
        data,
        code,
        d.values[k].father.as_ref().map(|f| f.0.as_str()),
        depth + 1,
    )?;
    Ok(up * d.pose(k))
}

/// The TCP of the tool a motion names, in the flange frame.
fn tool_frame(data: &Datas, code: &Code, text: &str) -> Result<Isometry3<f64>, Missing> {
    tool_chain(data, code, text.trim(), 0)
}

fn tool_chain(
    data: &Datas,
    code: &Code,
    text: &str,
    depth: usize,
) -> Result<Isometry3<f64>, Missing> {
    let Some(r) = reference(text) else {
        return Err(Missing::Unknown(format!(
            "tool '{}' is computed as the program runs",
            crate::escape_controls(text)
        )));
    };
    if r.name == "flange" {
        return Ok(Isometry3::identity());
    }
    if depth >= MAX_DEPTH {
        return Err(Missing::Unknown(format!(
            "the tool chain through {text} is more than {MAX_DEPTH} deep (a cycle)"
        )));
    }
    let Some(key) = r.key else {
        return Err(Missing::Unknown(format!(
            "tool {text}: its index is computed as the program runs"
        )));
    };
    let Some(d) = data.get(&r.name) else {
        return Err(match code.locals.get(&r.name) {
            Some(p) => Missing::Unknown(format!(
                "tool {text} is a local variable or parameter of {p}"
            )),
            None => Missing::Undeclared(text.to_string()),
        });
    };
    if d.kind != Kind::Tool {
        return Err(Missing::Unknown(format!(
            "{text} is a {}, not a tool",
            d.type_name
        )));
    }
    let Some(k) = d.value(&key) else {
        return Err(Missing::Undeclared(text.to_string()));
    };
    if let Some(at) = code.assigned_at(&d.name, &key) {
        return Err(Missing::Unknown(format!(
            "tool {text} is set as the program runs ({at})"
        )));
    }
    let father = d.values[k]
        .father
        .as_ref()
        .map_or("flange[0]", |f| f.0.as_str());
    let up = tool_chain(data, code, father, depth + 1)?;
    Ok(up * d.pose(k))
}

/// The text that writes an edit of a VAL3 number: an omitted attribute (the edit's span
/// empty) is inserted with its name, ` z="1.25"`; any other edit is kept. A text that is
/// not a finite number is kept as it is, for the job to refuse.
pub fn inserted(edit: ((usize, usize), String), name: &str) -> ((usize, usize), String) {
    let (span, text) = edit;
    if span.0 != span.1 || !text.parse::<f64>().is_ok_and(f64::is_finite) {
        return (span, text);
    }
    (span, format!(" {name}=\"{text}\""))
}

/// The number an edit writes: an inserted attribute's value ([`inserted`]), else the
/// edit's text.
pub fn edit_number(text: &str) -> &str {
    match text.strip_prefix(' ').and_then(|t| t.split_once("=\"")) {
        Some((name, value)) if name.bytes().all(|b| b.is_ascii_alphanumeric()) => {
            value.strip_suffix('"').unwrap_or(text)
        }
        _ => text,
    }
}

/// The name of joint `index` (from 0) of a `jointRx`: `j1`, `j2`, ….
pub fn joint_name(index: usize) -> String {
    format!("j{}", index + 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frames::xyz_intrinsic_near;
    use nalgebra::{Rotation3, Vector3};

    const DTX: &str = "\u{feff}<?xml version=\"1.0\" encoding=\"utf-8\"?>\r\n\
<Database xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" xmlns=\"http://www.staubli.com/robotics/VAL3/Data/2\">\r\n\
  <Datas>\r\n\
    <Data name=\"fPart\" access=\"public\" xsi:type=\"array\" type=\"frame\" size=\"1\">\r\n\
      <Value key=\"0\" x=\"1600\" y=\"250\" z=\"750\" rz=\"30\" fatherId=\"world[0]\" />\r\n\
    </Data>\r\n\
    <Data name=\"fSub\" access=\"public\" xsi:type=\"array\" type=\"frame\" size=\"1\">\r\n\
      <Value key=\"0\" x=\"10\" fatherId=\"fPart[0]\" />\r\n\
    </Data>\r\n\
    <Data name=\"tTorch\" access=\"public\" xsi:type=\"array\" type=\"tool\" size=\"1\">\r\n\
      <Value key=\"0\" z=\"180\" fatherId=\"flange[0]\" ioLink=\"valve1\" />\r\n\
    </Data>\r\n\
    <Data name=\"jHome\" access=\"public\" xsi:type=\"array\" type=\"jointRx\" size=\"1\">\r\n\
      <Value key=\"0\" j2=\"-90\" j3=\"90\" />\r\n\
    </Data>\r\n\
    <Data name=\"pSeam\" access=\"public\" xsi:type=\"array\" type=\"pointRx\" size=\"4\">\r\n\
      <Value key=\"0\" x=\"300\" y=\"100\" z=\"20\" rx=\"180\" rz=\"-30\" shoulder=\"lefty\" fatherId=\"fPart[0]\" />\r\n\
      <Value key=\"1\" x=\"320\" y=\"100\" rx=\"180\" fatherId=\"fSub[0]\" />\r\n\
      <Value key=\"2\" x=\"340\" fatherId=\"fGone[0]\" />\r\n\
      <Value key=\"3\" x=\"360\" fatherId=\"world[0]\" />\r\n\
    </Data>\r\n\
    <Data name=\"pRef\" access=\"public\" xsi:type=\"array\" type=\"pointRx\" size=\"1\">\r\n\
      <Value key=\"0\" x=\"1\" />\r\n\
    </Data>\r\n\
    <Data name=\"nCount\" access=\"public\" xsi:type=\"array\" type=\"num\" size=\"1\" />\r\n\
  </Datas>\r\n\
</Database>\r\n";

    const PGX: &str = "<?xml version=\"1.0\" encoding=\"utf-8\"?>\r\n\
<Programs xmlns=\"http://www.staubli.com/robotics/VAL3/Program/2\">\r\n\
  <Program name=\"start\" access=\"public\">\r\n\
    <Locals>\r\n      <Local name=\"lPoint\" type=\"pointRx\" xsi:type=\"array\" size=\"1\" />\r\n    </Locals>\r\n\
    <Code><![CDATA[begin\r\n\
  // movel(pRef, tTorch, mNom) is a comment\r\n\
  movej(jHome, tTorch, mNom)\r\n\
  movel(pSeam[0], tTorch, mNom)\r\n\
  nTraj = movel(appro(pSeam[1], trApp), tTorch, mNom)\r\n\
  movec(pSeam[1], pSeam[2], tTorch, mNom)\r\n\
  movel(lPoint, tTorch, mNom)\r\n\
  movel(here(tTorch, world), tTorch, mNom)\r\n\
  movel(pMissing, tTorch, mNom)\r\n\
  movelf(pSeam[3], tTorch, mNom)\r\n\
  pSeam[3] = here(tTorch, world)\r\n\
  movel(pSeam[3], tTorch, mNom)\r\n\
  nCount = distance(pRef, pSeam[0])\r\n\
  waitEndMove()\r\n\
end]]></Code>\r\n\
  </Program>\r\n\
</Programs>\r\n";

    fn statuses(p: &Program) -> Vec<String> {
        p.targets
            .iter()
            .map(|t| {
                let s = match (&t.refused, &t.kind) {
                    (Some(r), _) => r.reason.as_str(),
                    (None, TargetKind::Cartesian(_)) => "cartesian",
                    (None, TargetKind::Joints(_)) => "joints",
                    (None, _) => "other",
                };
                format!("{} {s}", t.name)
            })
            .collect()
    }

    fn read_both() -> Program {
        read(
            &Source::new("app.dtx", DTX.as_bytes()),
            &[Source::new("start.pgx", PGX.as_bytes())],
        )
        .unwrap()
    }

    #[test]
    fn motions_name_the_targets_and_every_other_use_is_reported() {
        let p = read_both();
        assert_eq!(
            statuses(&p),
            [
                "jHome[0] joints",
                "pSeam[0] cartesian",
                "pSeam[1] cartesian",
                "pSeam[2] cartesian",
                "pSeam[3] dynamic",
                "pRef[0] not_moved",
                "movel relative",
                "movel dynamic",
                "movel dynamic",
                "movel not_declared",
                "movelf unknown_motion",
            ]
        );
        let detail = |name: &str| {
            p.targets
                .iter()
                .find(|t| t.name == name)
                .and_then(|t| t.refused.as_ref())
                .map(|r| r.detail.clone())
                .unwrap()
        };
        assert_eq!(
            detail("pRef[0]"),
            "no motion moves to it; the code uses it otherwise (first at start.pgx:19:19)"
        );
        assert_eq!(
            detail("pSeam[3]"),
            "assigned as the program runs (start.pgx:17:1)"
        );
        // The omitted attributes: zeros with an empty span after the last one written.
        let TargetKind::Cartesian(c) = &p.targets[1].kind else {
            unreachable!()
        };
        let Some(Orientation::XyzIntrinsicDeg(r)) = c.orientation else {
            unreachable!()
        };
        assert_eq!(r.map(|n| n.value), [180.0, 0.0, -30.0]);
        let rx_end = DTX.find("rx=\"180\" rz").unwrap() + "rx=\"180\"".len();
        assert_eq!(r[1].span, (rx_end, rx_end));
        // Frames: the fixture chained to the world, the torch to the flange.
        let u = &p.targets[1].uses[0];
        let part = Isometry3::from_parts(
            Translation3::new(1600.0, 250.0, 750.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 30f64.to_radians()),
        );
        assert!(
            (u.base.unwrap().to_homogeneous() - part.to_homogeneous())
                .abs()
                .max()
                < 1e-9
        );
        assert_eq!(
            u.tool.unwrap().translation.vector,
            Vector3::new(0.0, 0.0, 180.0)
        );
        assert_eq!(u.elsewhere.as_deref(), Some("start.pgx:10:1"));
        // A chain of two frames.
        let u = &p.targets[2].uses[0];
        let sub = part * Translation3::new(10.0, 0.0, 0.0);
        assert!(
            (u.base.unwrap().to_homogeneous() - sub.to_homogeneous())
                .abs()
                .max()
                < 1e-9
        );
        // A father the data does not hold: named.
        assert_eq!(
            p.targets[3].uses[0].undeclared,
            vec![Undeclared {
                base: true,
                name: "fGone[0]".into()
            }]
        );
    }

    #[test]
    fn the_angles_turn_about_x_then_the_new_y_then_the_new_z() {
        let r = rotation_from_xyz_intrinsic_deg([30.0, 40.0, 50.0]);
        let reference = Rotation3::from_axis_angle(&Vector3::x_axis(), 30f64.to_radians())
            * Rotation3::from_axis_angle(&Vector3::y_axis(), 40f64.to_radians())
            * Rotation3::from_axis_angle(&Vector3::z_axis(), 50f64.to_radians());
        assert!((r.matrix() - reference.matrix()).abs().max() < 1e-12);
        // rx 90: y goes onto z.
        let r = rotation_from_xyz_intrinsic_deg([90.0, 0.0, 0.0]);
        assert!((r * Vector3::y() - Vector3::z()).norm() < 1e-12);
        // Angles read back from a rotation rebuild it; at ry = 90° rx is kept.
        for v in [
            [10.0, -20.0, 170.0],
            [-135.0, 60.0, 5.0],
            [25.0, 90.0, 40.0],
            [0.0, -90.0, 0.0],
        ] {
            let r = rotation_from_xyz_intrinsic_deg(v);
            let near = xyz_intrinsic_near(&r, v);
            let back = rotation_from_xyz_intrinsic_deg(near);
            assert!(
                (r.matrix() - back.matrix()).abs().max() < 1e-9,
                "{v:?} {near:?}"
            );
            assert!((near[0] - v[0]).abs() < 1e-9, "{v:?} {near:?}");
        }
    }

    #[test]
    fn a_point_handed_to_a_program_is_not_followed_into_its_parameter() {
        let dtx = "<Database><Datas><Data name=\"pPart\" type=\"pointRx\">\n\
            <Value key=\"2\" x=\"1\" /></Data></Datas></Database>\n";
        let start = "<Programs><Program name=\"start\"><Code><![CDATA[\ncall pick(pPart[2])\n]]></Code></Program></Programs>\n";
        let pick = "<Programs><Program name=\"pick\"><Parameters><Parameter name=\"x_pTarget\" type=\"pointRx\" /></Parameters>\n\
            <Code><![CDATA[\nmovel(x_pTarget, flange, mNom)\n]]></Code></Program></Programs>\n";
        let p = read(
            &Source::new("a.dtx", dtx.as_bytes()),
            &[
                Source::new("start.pgx", start.as_bytes()),
                Source::new("pick.pgx", pick.as_bytes()),
            ],
        )
        .unwrap();
        assert_eq!(statuses(&p), ["pPart[2] not_moved", "movel dynamic"]);
        let why = |i: usize| p.targets[i].refused.as_ref().unwrap().detail.clone();
        assert_eq!(
            why(0),
            "no motion moves to it; the code uses it otherwise (first at start.pgx:2:11)"
        );
        assert!(
            why(1).ends_with(
                "x_pTarget is a local variable or parameter of pick, set as the program runs"
            ),
            "{}",
            why(1)
        );
    }

    #[test]
    fn a_data_file_taken_for_another_dialect_is_refused_by_name() {
        let err = crate::dialect::check(&Source::new("w.src", DTX.as_bytes()), Format::Krl, false)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("this reads as Stäubli VAL3 ('<Database' at its line 2), not KUKA KRL"),
            "{err}"
        );
        crate::dialect::check(&Source::new("w.dtx", DTX.as_bytes()), Format::Val3, false).unwrap();
    }

    #[test]
    fn an_omitted_attribute_is_inserted_with_its_name() {
        assert_eq!(
            inserted(((5, 5), "1.25".into()), "z"),
            ((5, 5), " z=\"1.25\"".into())
        );
        assert_eq!(
            inserted(((5, 8), "1.25".into()), "z"),
            ((5, 8), "1.25".into())
        );
        // A number that is not finite is left for the job to refuse.
        assert_eq!(
            inserted(((5, 5), "NaN".into()), "z"),
            ((5, 5), "NaN".into())
        );
    }

    #[test]
    fn a_points_config_is_read_as_written_and_same_or_free_is_the_controllers() {
        let config = |attributes: &str| {
            let dtx = format!(
                "<Database><Datas><Data name=\"p\" type=\"pointRx\">\n<Value key=\"0\" x=\"1\" {attributes} />\n</Data></Datas></Database>"
            );
            let p = read(&Source::new("a.dtx", dtx.as_bytes()), &[]).unwrap();
            let TargetKind::Cartesian(c) = &p.targets[0].kind else {
                panic!("{:?}", p.targets[0].kind)
            };
            c.config
        };
        assert_eq!(
            config("shoulder=\"righty\" elbow=\"enegative\" wrist=\"wpositive\""),
            ConfigHint::Val3 {
                righty: Some(true),
                elbow_positive: Some(false),
                wrist_positive: Some(true),
            }
        );
        assert_eq!(
            config("shoulder=\"lefty\" elbow=\"efree\" wrist=\"wnegative\""),
            ConfigHint::Val3 {
                righty: Some(false),
                elbow_positive: None,
                wrist_positive: Some(false),
            }
        );
        // Omitted (SRS's default, `same`) or free throughout: the controller chooses.
        assert_eq!(config(""), ConfigHint::None);
        assert_eq!(
            config("shoulder=\"ssame\" elbow=\"esame\" wrist=\"wfree\""),
            ConfigHint::None
        );
        // A value that is none of VAL3's: where it is written, and what was expected.
        let bad = config("shoulder=\"lefty\" elbow=\"up\"");
        let ConfigHint::Unreadable { span, expected } = bad else {
            panic!("{bad:?}")
        };
        assert_eq!(expected, "elbow is epositive, enegative, esame or efree");
        let line = "<Value key=\"0\" x=\"1\" shoulder=\"lefty\" elbow=\"up\" />";
        let start = "<Database><Datas><Data name=\"p\" type=\"pointRx\">\n".len();
        let at = start + line.find("up").unwrap();
        assert_eq!(span, (at, at + 2));
    }

    #[test]
    fn malformed_files_are_located() {
        let err = |dtx: &str| {
            read(&Source::new("a.dtx", dtx.as_bytes()), &[])
                .unwrap_err()
                .to_string()
        };
        let head =
            "<?xml version=\"1.0\"?>\n<Database>\n<Datas>\n<Data name=\"p\" type=\"pointRx\">\n";
        assert_eq!(
            err(&format!(
                "{head}<Value key=\"0\" x=\"1.5mm\" />\n</Data></Datas></Database>\n"
            )),
            "a.dtx:5:19: x must be a number, found '1.5mm'"
        );
        assert_eq!(
            err(&format!("{head}<Value key=\"0\" x=\"1.5")),
            "a.dtx:5:18: an attribute's value not closed: the file ends inside it"
        );
        assert_eq!(
            err(&format!("{head}<Value key=\"0\" x=\"1\" />\n")),
            "a.dtx:4:2: <Data> is not closed: the file ends inside it"
        );
        assert_eq!(
            err(&format!(
                "{head}<Value key=\"0\" />\n<Value key=\"0\" />\n</Data></Datas></Database>"
            )),
            "a.dtx:6:13: the key 0 twice in p"
        );
        assert_eq!(
            err("<Datas></Database>"),
            "a.dtx:1:8: </Database> closes <Datas> (line 1)"
        );
        assert_eq!(
            err("<Datas/>"),
            "a.dtx:1:1: not a VAL3 data file: no <Database> element"
        );
        let err = read(
            &Source::new("a.dtx", b"<Database/>"),
            &[Source::new(
                "s.pgx",
                b"<Programs><Program name=\"s\"><Code><![CDATA[movel(",
            )],
        )
        .unwrap_err()
        .to_string();
        assert_eq!(
            err,
            "s.pgx:1:35: a CDATA section not closed (']]>' missing)"
        );
    }

    /// RoboDK's VAL3 data: three points in a frame of the cell, a tool.
    const RDK_DTX: &str = "<?xml version=\"1.0\" encoding=\"utf-8\" ?>\n\
<Database xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" xmlns=\"http://www.staubli.com/robotics/VAL3/Data/2\">\n\
  <Datas>\n\
    <Data name=\"fPartReal\" access=\"public\" xsi:type=\"array\" type=\"frame\" size=\"1\">\n\
      <Value key=\"0\" x=\"1500.000\" y=\"0.000\" z=\"500.000\" rx=\"0.000\" ry=\"0.000\" rz=\"0.000\" fatherId=\"world[0]\" />\n\
    </Data>\n\
    <Data name=\"pPoint\" access=\"public\" xsi:type=\"array\" type=\"pointRx\" size=\"3\">\n\
      <Value key=\"0\" x=\"250.000\" y=\"40.000\" z=\"450.000\" rx=\"90.000\" ry=\"60.000\" rz=\"-90.000\" fatherId=\"fPartReal[0]\" />\n\
      <Value key=\"1\" x=\"300.000\" y=\"40.000\" z=\"450.000\" rx=\"90.000\" ry=\"60.000\" rz=\"-90.000\" fatherId=\"world[0]\" />\n\
      <Value key=\"2\" x=\"300.000\" y=\"90.000\" z=\"450.000\" rx=\"90.000\" ry=\"60.000\" rz=\"-90.000\" fatherId=\"world[0]\" />\n\
    </Data>\n\
  </Datas>\n\
</Database>\n";

    /// A RoboDK program `name` with the parameters and locals `decl` and the code `code`.
    fn rdk_pgx(name: &str, decl: &str, code: &str) -> String {
        format!(
            "<?xml version=\"1.0\" encoding=\"utf-8\" ?>\n\
<Programs xmlns:xsi=\"http://www.w3.org/2001/XMLSchema-instance\" xmlns=\"http://www.staubli.com/robotics/VAL3/Program/2\">\n\
  <Program name=\"{name}\" access=\"public\">\n{decl}\
    <Code><![CDATA[\nbegin\n{code}end\n      ]]></Code>\n  </Program>\n</Programs>\n"
        )
    }

    fn read_rdk(programs: &[(&str, String)]) -> Program {
        let sources: Vec<Source> = programs
            .iter()
            .map(|(n, t)| Source::new(n, t.as_bytes()))
            .collect();
        read(&Source::new("rt.dtx", RDK_DTX.as_bytes()), &sources).unwrap()
    }

    #[test]
    fn a_frame_or_point_the_code_links_is_not_known() {
        let set_link = rdk_pgx(
            "setLink",
            "    <Parameters xmlns=\"http://www.staubli.com/robotics/VAL3/Param/1\">\n\
      <Parameter name=\"x_fCellule\" type=\"frame\" xsi:type=\"element\" use=\"reference\" />\n\
    </Parameters>\n",
            "  link(fPartReal,x_fCellule)\n",
        );
        let start = rdk_pgx(
            "start",
            "",
            "  link(pPoint[1], world)\n  movel(pPoint[0],tCad[0],mSpeed[0])\n\
  movel(pPoint[1],tCad[0],mSpeed[0])\n  movel(pPoint[2],tCad[0],mSpeed[0])\n",
        );
        let p = read_rdk(&[("setLink.pgx", set_link), ("start.pgx", start)]);
        let unknown: Vec<String> = p
            .targets
            .iter()
            .map(|t| t.uses[0].unknown.join("; "))
            .collect();
        assert_eq!(
            unknown,
            [
                "frame fPartReal[0] is linked to another frame as the program runs (setLink.pgx:9:8)",
                "pPoint[1] is linked to a frame as the program runs (start.pgx:6:8)",
                "",
            ]
        );
    }

    #[test]
    fn a_local_or_parameter_hides_the_global_of_its_name() {
        for decl in [
            "    <Locals>\n      <Local name=\"pPoint\" type=\"pointRx\" xsi:type=\"array\" size=\"3\" />\n    </Locals>\n",
            "    <Parameters xmlns=\"http://www.staubli.com/robotics/VAL3/Param/1\">\n      <Parameter name=\"pPoint\" type=\"pointRx\" xsi:type=\"array\" use=\"reference\" />\n    </Parameters>\n",
        ] {
            let start = rdk_pgx("start", decl, "  nTraj=movel(pPoint[0],tCad[0],mSpeed[0])\n");
            let p = read_rdk(&[("start.pgx", start)]);
            assert_eq!(
                statuses(&p),
                [
                    "pPoint[0] not_moved",
                    "pPoint[1] not_moved",
                    "pPoint[2] not_moved",
                    "movel dynamic"
                ]
            );
            assert!(p.targets[3].refused.as_ref().unwrap().detail.ends_with(
                "pPoint is a local variable or parameter of start, set as the program runs"
            ));
        }
    }

    #[test]
    fn a_dollar_motion_is_an_unknown_motion() {
        let start = rdk_pgx(
            "start",
            "",
            "  nTraj=$Xmovel(pPoint[1],nTarget0[0],tCad[0],mSpeed[0])\n",
        );
        let p = read_rdk(&[("start.pgx", start)]);
        assert_eq!(
            statuses(&p),
            [
                "pPoint[0] not_moved",
                "pPoint[1] unknown_motion",
                "pPoint[2] not_moved",
                "$Xmovel unknown_motion"
            ]
        );
    }

    #[test]
    fn values_handed_to_a_program_that_moves_to_them_are_reported() {
        // RoboDK's post without data: each joint target a call of MoveJoint.
        let move_joint = rdk_pgx(
            "MoveJoint",
            "    <Parameters xmlns=\"http://www.staubli.com/robotics/VAL3/Param/1\">\n\
      <Parameter name=\"x_nJ1\" type=\"num\" xsi:type=\"element\" />\n\
      <Parameter name=\"x_nJ2\" type=\"num\" xsi:type=\"element\" />\n\
    </Parameters>\n    <Locals>\n      <Local name=\"l_jJoint\" type=\"joint\" xsi:type=\"array\" size=\"1\" />\n    </Locals>\n",
            "  l_jJoint.j1 = x_nJ1\n  l_jJoint.j2 = x_nJ2\n  movej(l_jJoint,tCurrentTool ,mCurrentSpeed)\n",
        );
        let main = rdk_pgx(
            "main",
            "",
            "  call MoveJoint(0.00000,0.00000)\n  call MoveJoint(0.05064,0.10127)\n  movel(pPoint[2],tCad[0],mSpeed[0])\n",
        );
        let p = read_rdk(&[("MoveJoint.pgx", move_joint), ("main.pgx", main)]);
        assert_eq!(
            statuses(&p),
            [
                "pPoint[0] not_moved",
                "pPoint[1] not_moved",
                "pPoint[2] cartesian",
                "movej dynamic",
                "call dynamic",
                "call dynamic"
            ]
        );
        assert_eq!(
            p.targets[5].refused.as_ref().unwrap().detail,
            "call MoveJoint(0.05064,0.10127) at main.pgx:7:8: MoveJoint moves to what it is handed \
             (movej(l_jJoint,tCurrentTool ,mCurrentSpeed) at MoveJoint.pgx:15:3), values the data does not hold: not corrected"
        );
    }

    #[test]
    fn the_format_of_srs_6_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let pjx = dir.path().join("NovaAplicacio.pjx");
        std::fs::write(
            &pjx,
            "\u{feff}<?xml version=\"1.0\" encoding=\"utf-8\"?>\r\n<project xmlns=\"ProjectNameSpace\">\r\n\
  <parameters version=\"s6.8\" stackSize=\"5000\" millimeterUnit=\"true\" />\r\n  <programSection>\r\n\
    <program file=\"start.pgx\" />\r\n  </programSection>\r\n  <dataSection>\r\n\
    <data file=\"NovaAplicacio.dtx\" />\r\n  </dataSection>\r\n</project>",
        )
        .unwrap();
        let err = Application::locate(&pjx).err().unwrap().to_string();
        assert!(
            err.ends_with("NovaAplicacio.pjx:1:1: a VAL3 project in the format of Stäubli Robotics Suite 6 (<project>, version s6.8), which this reader does not read: it reads the format of SRS 7 and later (<Project>, <Database> with <Data> and <Value>, <Programs>)"),
            "{err}"
        );
        let dtx = "\u{feff}<?xml version=\"1.0\" encoding=\"utf-8\"?>\r\n<dataList xmlns=\"DataNameSpace\">\r\n  <pointSection />\r\n</dataList>";
        let err = read(&Source::new("a.dtx", dtx.as_bytes()), &[]).unwrap_err();
        assert!(err.to_string().starts_with(
            "a.dtx:2:1: a VAL3 data file in the format of Stäubli Robotics Suite 6 (<dataList>)"
        ));
    }
}
