//! Values of KRL expressions as far as they can be known before run time: integers, reals,
//! booleans, enum literals, frame data (`FDAT`), positions (`FRAME POS E6POS AXIS E6AXIS`,
//! possibly partial) and user structures (`STRUC`: members by name, nested), each position
//! remembering the aggregate its numbers were read from so that compensation can write them
//! back. Anything that depends on run time (inputs, sensor
//! values, unknown functions) is `Unknown` with the reason.

use crate::kinematics::Pose;
use crate::krl::{Aggregate, Expr, Number, SourceFile, Span};
use std::borrow::Cow;

use super::workspace::FileId;

/// Where a position's numbers are written.
#[derive(Clone, Copy, Debug)]
pub struct Origin<'f> {
    pub file: FileId,
    pub agg: &'f Aggregate,
    /// The declared variable (or array element) holding the aggregate, if any.
    pub var: Option<VarRef>,
    /// A geometric-operator prefix: the motion's position is `prefix : this`; an index into
    /// [`Simulation::prefixes`](super::Simulation::prefixes) (a frame here would make every
    /// stop of a million-target program 100 bytes larger).
    pub prefix: Option<u32>,
    /// A geometric-operator suffix: the motion's position is `this : suffix` (a point with
    /// an offset applied after it, `P1 : {X 10}`), an index into the same table.
    pub suffix: Option<u32>,
    /// Bit `k` set: the position's component `k` is the value of the aggregate's own literal
    /// (read once by the walk; the rewrite need not read the number again).
    pub literals: u8,
    /// The aggregate gives external axes (`E1`…`E6`) other than zero.
    pub external: bool,
}

/// Decimals a literal is written with (the digits after its dot).
pub fn literal_decimals(text: &[u8]) -> usize {
    text.iter().position(|&b| b == b'.').map_or(0, |p| {
        text[p + 1..]
            .iter()
            .take_while(|b| b.is_ascii_digit())
            .count()
    })
}

/// A declared variable (name span in its file) or one initialised array element.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VarRef {
    pub file: FileId,
    /// The name in the declaration (or the array element's assignment).
    pub name: Span,
    /// The statement (line) that declares / initialises it.
    pub stmt: Span,
    pub element: bool,
    /// For a point given its value by an assignment statement (`stmt`), its declaration
    /// without a value: a copy of the point is declared there too.
    pub declared: Option<Declared>,
}

/// The declaration (`DECL E6AXIS XHOME`) of a point assigned by a statement.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Declared {
    pub file: FileId,
    /// Where the declaration stands (its line is the one copied after).
    pub stmt: Span,
    /// The type's name in it.
    pub ty: Span,
}

/// A (possibly partial) position.
#[derive(Clone, Copy, Debug)]
pub struct Pos<'f> {
    pub v: Components,
    pub s: Option<u8>,
    pub t: Option<u8>,
    pub origin: Option<Origin<'f>>,
}

/// The numbers of a position by what they are, in the order the aggregate names them;
/// `None`: not given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Components {
    /// Axis angles `A1..A6`, degrees.
    Axes([Option<f64>; 6]),
    /// A Cartesian pose `X Y Z A B C`, mm and degrees.
    Pose([Option<f64>; 6]),
}

impl Components {
    /// Numbers named as `naming` says.
    pub fn named(naming: Naming, v: [Option<f64>; 6]) -> Components {
        match naming {
            Naming::Axes => Components::Axes(v),
            Naming::Cartesian => Components::Pose(v),
        }
    }

    /// How the numbers are named.
    pub fn naming(&self) -> Naming {
        match self {
            Components::Axes(_) => Naming::Axes,
            Components::Pose(_) => Naming::Cartesian,
        }
    }

    /// A whole pose.
    pub fn of_pose(pose: &Pose) -> Components {
        Components::Pose(pose.to_array().map(Some))
    }

    pub fn is_axes(&self) -> bool {
        matches!(self, Components::Axes(_))
    }

    /// The six numbers, whatever they are.
    pub fn values(&self) -> &[Option<f64>; 6] {
        match self {
            Components::Axes(v) | Components::Pose(v) => v,
        }
    }

    pub fn values_mut(&mut self) -> &mut [Option<f64>; 6] {
        match self {
            Components::Axes(v) | Components::Pose(v) => v,
        }
    }
}

impl Pos<'_> {
    /// A position that is only numbers (no S, T, nor place in the source).
    pub fn numbers(v: Components) -> Self {
        Pos {
            v,
            s: None,
            t: None,
            origin: None,
        }
    }

    pub fn is_complete(&self) -> bool {
        self.v.values().iter().all(Option::is_some)
    }

    /// A position read as a frame: the components it does not give are zero.
    pub fn frame_pose(&self) -> Pose {
        Pose::from_array(self.v.values().map(|x| x.unwrap_or(0.0)))
    }
}

/// `FDAT`: the tool, base and interpolation frame of an inline form's point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Fdat {
    pub tool_no: Option<i64>,
    pub base_no: Option<i64>,
    /// `IPO_FRAME #TCP` (external TCP).
    pub external_tcp: bool,
}

// Positions dominate the values a program moves with: boxing them would allocate per motion.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Value<'f> {
    Int(i64),
    Real(f64),
    Bool(bool),
    /// `#NAME`, upper case, without `#`.
    Enum(Vec<u8>),
    Pos(Pos<'f>),
    Fdat(Fdat),
    /// `LDAT` (an inline form's motion data): its orientation type `ORI_TYP` (`#VAR`,
    /// `#CONSTANT`, `#JOINT`: upper case, without `#`), when written as a constant.
    Ldat(Option<Vec<u8>>),
    /// A user structure: its members set so far (upper-case name, value), in order.
    Struc(Vec<(Vec<u8>, Value<'f>)>),
    /// Not known before run time, and why.
    Unknown(String),
}

impl<'f> Value<'f> {
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            Value::Int(i) => Some(*i as f64),
            Value::Real(r) => Some(*r),
            _ => None,
        }
    }

    pub fn as_int(&self) -> Option<i64> {
        match self {
            Value::Int(i) => Some(*i),
            Value::Real(r) if r.fract() == 0.0 && r.abs() < 9e15 => Some(*r as i64),
            _ => None,
        }
    }

    pub fn is_unknown(&self) -> bool {
        matches!(self, Value::Unknown(_))
    }
}

/// The value of a bit literal `'B010'`, `'H1F'` (decimal otherwise).
pub fn bits_value(text: &[u8]) -> Option<i64> {
    let inner = text.strip_prefix(b"'")?.strip_suffix(b"'")?;
    let (radix, digits) = match inner.first()? {
        b'B' | b'b' => (2, &inner[1..]),
        b'H' | b'h' => (16, &inner[1..]),
        _ => (10, inner),
    };
    i64::from_str_radix(std::str::from_utf8(digits).ok()?, radix).ok()
}

/// What the six components of a position are: axis angles `A1..A6` (degrees) or a Cartesian
/// pose `X Y Z A B C` (mm and degrees).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Naming {
    Axes,
    Cartesian,
}

impl Naming {
    /// How a target's aggregate names what it programs: axes `A1..A6` or `X … C`.
    pub fn of(programmed: &crate::motion::form::Programmed) -> Naming {
        match programmed {
            crate::motion::form::Programmed::Axes(_) => Naming::Axes,
            crate::motion::form::Programmed::Pose(_) => Naming::Cartesian,
        }
    }

    /// The member names of the components.
    pub fn names(self) -> [&'static str; 6] {
        match self {
            Naming::Axes => AXIS_NAMES,
            Naming::Cartesian => CARTESIAN_NAMES,
        }
    }

    /// Whether component `k` is an angle (degrees), else a length (mm).
    pub fn is_angle(self, k: usize) -> bool {
        self == Naming::Axes || k >= 3
    }
}

/// The naming and index of an aggregate member's name: Cartesian `X Y Z A B C`, or axis
/// `A1..A6`.
pub fn component(name: &[u8]) -> Option<(Naming, usize)> {
    Some(match name {
        // One lookup: the walk asks this of every member of a million positions.
        [c] => match CARTESIAN_COMPONENT[usize::from(*c)] {
            0 => return None,
            k => (Naming::Cartesian, usize::from(k - 1)),
        },
        [a, d @ b'1'..=b'6'] if a.eq_ignore_ascii_case(&b'A') => {
            (Naming::Axes, (d - b'1') as usize)
        }
        _ => return None,
    })
}

/// Per byte, 1 + the index of the Cartesian component that letter names (either case), or 0.
static CARTESIAN_COMPONENT: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut k = 0;
    while k < 6 {
        let c = CARTESIAN_NAMES[k].as_bytes()[0];
        t[c as usize] = k as u8 + 1;
        t[c.to_ascii_lowercase() as usize] = k as u8 + 1;
        k += 1;
    }
    t
};

/// The member names of a position's components.
pub const CARTESIAN_NAMES: [&str; 6] = ["X", "Y", "Z", "A", "B", "C"];
pub const AXIS_NAMES: [&str; 6] = ["A1", "A2", "A3", "A4", "A5", "A6"];

/// The number a member's value expression stands for when it is a literal (or a negated one).
pub fn literal(e: &Expr) -> Option<f64> {
    literal_number(e).map(|(negative, n)| if negative { -n.value } else { n.value })
}

/// The number a literal ([`literal`]) is written with, and whether it is negated.
fn literal_number(e: &Expr) -> Option<(bool, &Number)> {
    match e {
        Expr::Number(n) => Some((false, n)),
        Expr::Unary(u) => match (&u.op, &u.operand) {
            (crate::krl::UnOp::Neg, Expr::Number(n)) => Some((true, n)),
            (crate::krl::UnOp::Plus, Expr::Number(n)) => Some((false, n)),
            _ => None,
        },
        Expr::Paren(p) => literal_number(&p.inner),
        _ => None,
    }
}

/// The value of a numeric literal: an integer when written as one (and exact in an f64).
pub fn number<'f>(n: &Number) -> Value<'f> {
    if n.integer && n.value.abs() < 9e15 {
        Value::Int(n.value as i64)
    } else {
        Value::Real(n.value)
    }
}

/// Reads an aggregate as a position or frame data, evaluating member values with `eval`.
pub fn aggregate<'f>(
    file: &'f SourceFile,
    id: FileId,
    agg: &'f Aggregate,
    eval: impl FnMut(&'f Expr) -> Value<'f>,
) -> Value<'f> {
    match kept_position(file, id, agg) {
        Some(pos) => Value::Pos(pos),
        None => decoded(file, id, agg, eval),
    }
}

/// [`aggregate`], each member decoded (any aggregate).
fn decoded<'f>(
    file: &'f SourceFile,
    id: FileId,
    agg: &'f Aggregate,
    mut eval: impl FnMut(&'f Expr) -> Value<'f>,
) -> Value<'f> {
    let src = file.source();
    let mut pos = Pos {
        v: Components::Pose([None; 6]),
        s: None,
        t: None,
        origin: Some(Origin {
            file: id,
            agg,
            var: None,
            prefix: None,
            suffix: None,
            literals: 0,
            external: false,
        }),
    };
    let mut literals = 0u8;
    let mut fdat = Fdat::default();
    let (mut cartesian, mut axis, mut is_fdat) = (false, false, false);
    let mut ldat: Option<Option<Vec<u8>>> = None;
    // Members that are neither position components nor frame or motion data: a structure's.
    let mut others: Vec<(&[u8], crate::krl::RawMember<'f>)> = Vec::new();
    // A plain number member is handed out by value (not borrowed from the file).
    let mut eval = |v: &Cow<'f, Expr>| match v {
        Cow::Borrowed(e) => eval(e),
        Cow::Owned(Expr::Number(n)) => number(n),
        Cow::Owned(e) => Value::Unknown(format!("a member value at {:?}", e.span())),
    };
    for raw in file.raw_members(agg) {
        let name = &src[raw.name().range()];
        // Position components first: nearly every member is one (no name is both a component
        // and one of the words below).
        if let Some((naming, k)) = component(name) {
            // A plain `NAME number` (nearly every member of a CAM program) is read straight
            // from its bytes, no expression built.
            let plain = match raw {
                crate::krl::RawMember::Plain { number, kept, .. } => {
                    crate::krl::RawMember::plain_value_kept(src, number, kept)
                }
                _ => None,
            };
            let v = match plain {
                Some(v) => {
                    literals |= 1 << k;
                    v
                }
                None => {
                    let m = file.member_of(raw);
                    match literal_number(&m.value) {
                        Some((negative, n)) => {
                            literals |= 1 << k;
                            if negative {
                                -n.value
                            } else {
                                n.value
                            }
                        }
                        None => match eval(&m.value).as_f64() {
                            Some(v) => {
                                // Computed: the number cannot be written back in place.
                                pos.origin = None;
                                v
                            }
                            None => {
                                return Value::Unknown(format!(
                                    "{} of the position is computed at run time",
                                    String::from_utf8_lossy(name)
                                ))
                            }
                        },
                    }
                }
            };
            pos.v.values_mut()[k] = Some(v);
            match naming {
                Naming::Axes => axis = true,
                Naming::Cartesian => cartesian = true,
            }
            continue;
        }
        let m = file.member_of(raw);
        let is = |word: &str| name.eq_ignore_ascii_case(word.as_bytes());
        match () {
            _ if is("S") || is("T") => {
                let v = match &*m.value {
                    Expr::Bits(s) => bits_value(file.text(*s)),
                    _ => eval(&m.value).as_int(),
                };
                let Some(v) = v else {
                    return Value::Unknown(format!(
                        "{} is not a constant",
                        String::from_utf8_lossy(name)
                    ));
                };
                if is("S") {
                    pos.s = Some(v as u8);
                } else {
                    pos.t = Some(v as u8);
                }
                cartesian = true;
            }
            _ if is("TOOL_NO") => {
                is_fdat = true;
                fdat.tool_no = eval(&m.value).as_int();
            }
            _ if is("BASE_NO") => {
                is_fdat = true;
                fdat.base_no = eval(&m.value).as_int();
            }
            _ if is("IPO_FRAME") => {
                is_fdat = true;
                fdat.external_tcp = matches!(&*m.value, Expr::Enum(s) if file.text(*s).eq_ignore_ascii_case(b"#TCP"));
            }
            _ if is("ORI_TYP") => {
                ldat = Some(match &*m.value {
                    Expr::Enum(s) => Some(file.text(*s)[1..].to_ascii_uppercase()),
                    _ => None,
                });
            }
            // E1..E6 of a position are carried unchanged; other members make a structure.
            _ => others.push((name, raw)),
        }
    }
    if let Some(o) = &mut pos.origin {
        // External axes other than zero: carried unchanged (the walker says so).
        o.external = others.iter().any(|(name, raw)| {
            matches!(name, [e, b'1'..=b'6'] if e.eq_ignore_ascii_case(&b'E'))
                && match raw {
                    crate::krl::RawMember::Plain { number, kept, .. } => {
                        crate::krl::RawMember::plain_value_kept(src, *number, *kept)
                            .is_some_and(|v| v != 0.0)
                    }
                    _ => literal(&file.member_of(*raw).value) != Some(0.0),
                }
        });
    }
    if !cartesian && !axis && !is_fdat && ldat.is_none() && !others.is_empty() {
        let members = others
            .into_iter()
            .map(|(name, raw)| {
                let m = file.member_of(raw);
                (name.to_ascii_uppercase(), eval(&m.value))
            })
            .collect();
        return Value::Struc(members);
    }
    if is_fdat {
        return Value::Fdat(fdat);
    }
    if let Some(ori) = ldat {
        return Value::Ldat(ori);
    }
    if axis && cartesian {
        return Value::Unknown("an aggregate mixing axis angles and Cartesian values".into());
    }
    let naming = if axis {
        Naming::Axes
    } else {
        Naming::Cartesian
    };
    pos.v = Components::named(naming, *pos.v.values());
    if let Some(o) = &mut pos.origin {
        o.literals = literals;
    }
    Value::Pos(pos)
}

/// The position of an aggregate whose members all name components of one naming and are
/// plain numbers whose values the tree kept (a streamed CAM line's): what [`aggregate`] makes
/// of it, read without decoding a member; `None` for any other aggregate.
fn kept_position<'f>(file: &'f SourceFile, id: FileId, agg: &'f Aggregate) -> Option<Pos<'f>> {
    let src = file.source();
    let mut v = [None; 6];
    let mut literals = 0u8;
    let mut naming = None;
    for raw in file.raw_members(agg) {
        let crate::krl::RawMember::Plain {
            name,
            number: _,
            kept: Some(value),
        } = raw
        else {
            return None;
        };
        let (named, k) = component(&src[name.range()])?;
        if *naming.get_or_insert(named) != named {
            return None;
        }
        v[k] = Some(value);
        literals |= 1 << k;
    }
    Some(Pos {
        v: Components::named(naming?, v),
        s: None,
        t: None,
        origin: Some(Origin {
            file: id,
            agg,
            var: None,
            prefix: None,
            suffix: None,
            literals,
            external: false,
        }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_literals() {
        assert_eq!(bits_value(b"'B010'"), Some(2));
        assert_eq!(bits_value(b"'B110101'"), Some(53));
        assert_eq!(bits_value(b"'H1F'"), Some(31));
        assert_eq!(bits_value(b"'x'"), None);
    }

    /// The kept values of a streamed window's aggregates give the position decoding its
    /// members gives: Cartesian and axis positions, a type, a repeated member, and (declined,
    /// decoded) mixed namings, external axes, S and T, an empty aggregate.
    #[test]
    fn kept_positions_are_the_decoded_ones() {
        let lines = [
            "LIN {X 1.5,Y -2,Z 0.000,A 0,B 90.25,C -180} C_DIS",
            "PTP {A1 -12.500,A2 -85,A3 105.5,A4 0,A5 70,A6 -12.5}",
            "LIN {E6POS: X 1, Y 2}",
            "LIN {X 1, y -3.25, z 7.}",
            "LIN {X 1, A1 2}",
            "PTP {A1 1, E1 0}",
            "PTP {A1 1, E1 5.5}",
            "PTP {X 1, Y 2, Z 3, A 0, B 0, C 0, S 6, T 27}",
            "LIN {}",
        ];
        let mut text = String::from("DEF p( )\n");
        for i in 0..40 {
            text.push_str(lines[i % lines.len()]);
            text.push('\n');
        }
        text.push_str("END\n");
        let opts = crate::krl::StreamOptions {
            min_run: 3,
            window: 7,
        };
        let file = crate::krl::parse_streaming(text.into_bytes(), crate::krl::FileKind::Src, opts)
            .expect("parses");
        let (mut kept, mut declined) = (0, 0);
        for run in file.streamed_runs() {
            for w in run.windows() {
                let window = file.window(w);
                for (_, m) in window.motions() {
                    let Expr::Aggregate(_, a) = m.target else {
                        panic!("a literal target");
                    };
                    let agg = window.aggregate(a);
                    let want = format!("{:?}", decoded(&window, 3, agg, |_| Value::Int(0)));
                    match kept_position(&window, 3, agg) {
                        Some(pos) => {
                            assert_eq!(format!("{:?}", Value::Pos(pos)), want);
                            kept += 1;
                        }
                        None => declined += 1,
                    }
                }
            }
        }
        assert!(
            kept >= 15 && declined >= 15,
            "{kept} kept, {declined} declined"
        );
    }

    #[test]
    fn component_names() {
        for b in 0..=255u8 {
            let want = b"XYZABC"
                .iter()
                .position(|c| c.eq_ignore_ascii_case(&b))
                .map(|k| (Naming::Cartesian, k));
            assert_eq!(component(&[b]), want, "{b}");
        }
        assert_eq!(component(b"x"), Some((Naming::Cartesian, 0)));
        assert_eq!(component(b"C"), Some((Naming::Cartesian, 5)));
        assert_eq!(component(b"A6"), Some((Naming::Axes, 5)));
        assert_eq!(component(b"E1"), None);
        assert_eq!(component(b"A7"), None);
    }
}
