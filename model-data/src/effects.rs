//! The effect-file format (`--effects FILE.toml` on the host, `$SIMROD_EFFECTS` for the
//! firmware build): the TOML subset both read, parsed in one place so both accept the
//! same files with the same messages.
//!
//! ```toml
//! # comment
//! [controller_delay]          # a section per effect
//! delay_s = 0.012             # param = number
//!
//! differential_friction.coulomb_nm = 0.8          # dotted key (before any section)
//! coupling_damping = { damping_nm_s_per_rad = 2 } # inline table (before any section)
//! ```
//!
//! Numbers are TOML integers or floats (`3`, `-2.5`, `1e-3`, `1_000`, `inf`, `nan`,
//! `0x10`), read as f64 (the caller narrows to f32, as a TOML reader would give it).
//! Effect ids and parameter names are not checked here: this crate is a
//! build-dependency of `model-core` and cannot see its vocabulary. The caller applies
//! each [`Entry`] with `Effects::set`, which names unknown ids and parameters, and
//! checks ranges with `Effects::check`; [`EffectFile::locate`] says where to point.

/// A 1-based line and column (the column counts characters, as editors do).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pos {
    /// 1-based line.
    pub line: usize,
    /// 1-based column, in characters.
    pub col: usize,
}

/// A syntax error at a place in the file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LocatedError {
    /// Where.
    pub at: Pos,
    /// What is wrong and what was expected.
    pub msg: String,
}

/// An effect named in the file (a `[section]`, the first dotted key or inline table
/// naming it), in file order; also the effects named without parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    /// Effect id as written.
    pub id: String,
    /// Where the id is written.
    pub at: Pos,
}

/// One `param = value`, in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    /// Effect id.
    pub effect: String,
    /// Parameter name.
    pub param: String,
    /// The number, as TOML reads it.
    pub value: f64,
    /// Where the effect id of this entry is written (its section header for `[id]`).
    pub effect_at: Pos,
    /// Where the parameter name is written.
    pub param_at: Pos,
    /// Where the value is written.
    pub value_at: Pos,
}

/// A parsed effect file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EffectFile {
    /// Effects named, in file order, each once.
    pub sections: Vec<Section>,
    /// Parameters set, in file order, each (effect, param) once.
    pub entries: Vec<Entry>,
}

impl EffectFile {
    /// Where to point for a problem with `effect` (and `param`): the value of the
    /// parameter if the file sets it, else where the effect is named.
    pub fn locate(&self, effect: &str, param: Option<&str>) -> Option<Pos> {
        let entry = self.entries.iter().find(|e| e.effect == effect && Some(e.param.as_str()) == param);
        entry.map(|e| e.value_at).or_else(|| self.sections.iter().find(|s| s.id == effect).map(|s| s.at))
    }
}

/// How an effect's table was defined, for TOML's rules on defining a table twice.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Defined {
    Header,
    Dotted,
    Inline,
}

fn fail<T>(line: usize, text: &str, byte: usize, msg: impl Into<String>) -> Result<T, LocatedError> {
    Err(LocatedError { at: pos(line, text, byte), msg: msg.into() })
}

fn pos(line: usize, text: &str, byte: usize) -> Pos {
    Pos { line, col: text.get(..byte).map_or(byte, |s| s.chars().count()) + 1 }
}

fn is_bare_key(s: &str) -> bool {
    !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

/// The byte where the comment of a line starts (a `#` outside a basic or literal string).
fn comment_start(line: &str) -> usize {
    let mut quote: Option<char> = None;
    let mut escaped = false;
    for (i, c) in line.char_indices() {
        match quote {
            Some('"') if escaped => escaped = false,
            Some('"') if c == '\\' => escaped = true,
            Some(q) if c == q => quote = None,
            Some(_) => {}
            None if c == '"' || c == '\'' => quote = Some(c),
            None if c == '#' => return i,
            None => {}
        }
    }
    line.len()
}

/// Offset of the first non-blank byte at or after `from`.
fn skip_ws(s: &str, from: usize) -> usize {
    from + s.get(from..).map_or(0, |r| r.len() - r.trim_start_matches([' ', '\t']).len())
}

/// A TOML number (integer or float) as f64; `None` if `s` is not one.
pub fn parse_number(s: &str) -> Option<f64> {
    let (sign, body) = match s.as_bytes().first() {
        Some(b'+') => (1.0, &s[1..]),
        Some(b'-') => (-1.0, &s[1..]),
        _ => (1.0, s),
    };
    match body {
        "inf" => return Some(sign * f64::INFINITY),
        "nan" => return Some(f64::NAN),
        _ => {}
    }
    for (prefix, radix) in [("0x", 16), ("0o", 8), ("0b", 2)] {
        if let Some(digits) = body.strip_prefix(prefix) {
            // TOML allows no sign on these.
            if body.len() != s.len() || !underscores_ok(digits, radix) {
                return None;
            }
            return i64::from_str_radix(&digits.replace('_', ""), radix).ok().map(|v| v as f64);
        }
    }
    // Decimal: int [frac] [exp], underscores only between digits, no leading zeros.
    let (mantissa, exp) = match body.find(['e', 'E']) {
        Some(i) => (&body[..i], Some(&body[i + 1..])),
        None => (body, None),
    };
    let (int, frac) = match mantissa.split_once('.') {
        Some((i, f)) => (i, Some(f)),
        None => (mantissa, None),
    };
    let leading_zero = int.len() > 1 && int.starts_with('0');
    let exp_ok = exp.is_none_or(|e| underscores_ok(e.strip_prefix(['+', '-']).unwrap_or(e), 10));
    if leading_zero || !underscores_ok(int, 10) || !frac.is_none_or(|f| underscores_ok(f, 10)) || !exp_ok {
        return None;
    }
    // decimal -> f64, exactly as TOML readers do (the caller narrows to f32).
    s.replace('_', "").parse::<f64>().ok()
}

/// Digits of `radix`, at least one, with single underscores only between digits.
fn underscores_ok(s: &str, radix: u32) -> bool {
    !s.is_empty()
        && !s.starts_with('_')
        && !s.ends_with('_')
        && !s.contains("__")
        && s.chars().all(|c| c == '_' || c.is_digit(radix))
}

struct Parser {
    file: EffectFile,
    defined: Vec<(String, Defined)>,
}

impl Parser {
    fn define(&mut self, id: &str, how: Defined, at: Pos) -> Result<(), LocatedError> {
        match self.defined.iter().find(|(d, _)| d == id).map(|(_, h)| *h) {
            None => {
                self.defined.push((id.to_string(), how));
                self.file.sections.push(Section { id: id.to_string(), at });
                Ok(())
            }
            // More dotted keys add to the same implicit table.
            Some(Defined::Dotted) if how == Defined::Dotted => Ok(()),
            Some(_) => Err(LocatedError { at, msg: format!("effect `{id}` is defined twice") }),
        }
    }

    fn entry(
        &mut self,
        effect: &str,
        effect_at: Pos,
        param: &str,
        param_at: Pos,
        raw: &str,
        value_at: Pos,
    ) -> Result<(), LocatedError> {
        if !is_bare_key(param) {
            return Err(LocatedError {
                at: param_at,
                msg: format!("expected a parameter name, found `{param}`"),
            });
        }
        let Some(value) = parse_number(raw) else {
            return Err(LocatedError {
                at: value_at,
                msg: format!("{param}: expected a number, found `{raw}`"),
            });
        };
        if self.file.entries.iter().any(|e| e.effect == effect && e.param == param) {
            return Err(LocatedError { at: param_at, msg: format!("`{effect}.{param}` is given twice") });
        }
        self.file.entries.push(Entry {
            effect: effect.to_string(),
            param: param.to_string(),
            value,
            effect_at,
            param_at,
            value_at,
        });
        Ok(())
    }
}

/// Parse an effect file. Errors carry the place; callers add the file name.
pub fn parse_effect_file(text: &str) -> Result<EffectFile, LocatedError> {
    let mut p = Parser { file: EffectFile::default(), defined: Vec::new() };
    // The current `[section]` and where its id is written.
    let mut section: Option<(String, Pos)> = None;
    for (i, raw) in text.lines().enumerate() {
        let ln = i + 1;
        let line = &raw[..comment_start(raw)];
        let start = skip_ws(line, 0);
        let body = line[start..].trim_end();
        if body.is_empty() {
            continue;
        }
        if body.starts_with("[[") {
            return fail(ln, raw, start, "arrays of tables are not effect sections; expected `[effect_id]`");
        }
        if let Some(rest) = body.strip_prefix('[') {
            let Some(close) = rest.find(']') else {
                return fail(ln, raw, start, "expected `[effect_id]`");
            };
            let id_at = skip_ws(line, start + 1);
            let id = rest[..close].trim();
            if !is_bare_key(id) {
                return fail(ln, raw, id_at, format!("expected `[effect_id]`, found `[{}]`", &rest[..close]));
            }
            if !rest[close + 1..].trim().is_empty() {
                return fail(ln, raw, start + 1 + close + 1, "unexpected text after `]`");
            }
            let at = pos(ln, raw, id_at);
            p.define(id, Defined::Header, at)?;
            section = Some((id.to_string(), at));
            continue;
        }
        let Some(eq) = body.find('=') else {
            return fail(ln, raw, start, "expected `param = number` or `[effect_id]`");
        };
        let value_start = skip_ws(line, start + eq + 1);
        let value = line[value_start..].trim_end();
        // Key parts (dotted keys) with their positions.
        let mut parts: Vec<(&str, usize)> = Vec::new();
        let mut off = start;
        for part in body[..eq].split('.') {
            let lead = part.len() - part.trim_start().len();
            parts.push((part.trim(), off + lead));
            off += part.len() + 1;
        }
        for (k, at) in &parts {
            if !is_bare_key(k) {
                return fail(
                    ln,
                    raw,
                    *at,
                    format!("expected a bare key (letters, digits, `_`, `-`), found `{k}`"),
                );
            }
        }
        match (&section, parts.as_slice()) {
            (Some((id, id_at)), [(param, at)]) => {
                let (id, id_at) = (id.clone(), *id_at);
                p.entry(&id, id_at, param, pos(ln, raw, *at), value, pos(ln, raw, value_start))?;
            }
            (Some((id, _)), _) => {
                return fail(
                    ln,
                    raw,
                    start,
                    format!("[{id}]: expected `param = number`, found a dotted key"),
                );
            }
            (None, [(effect, e_at), (param, p_at)]) => {
                let e_pos = pos(ln, raw, *e_at);
                p.define(effect, Defined::Dotted, e_pos)?;
                p.entry(effect, e_pos, param, pos(ln, raw, *p_at), value, pos(ln, raw, value_start))?;
            }
            (None, [(effect, e_at)]) if value.starts_with('{') => {
                let e_pos = pos(ln, raw, *e_at);
                p.define(effect, Defined::Inline, e_pos)?;
                let Some(inner) = value.strip_prefix('{').and_then(|v| v.strip_suffix('}')) else {
                    return fail(ln, raw, value_start, "expected `{ param = number, ... }` on one line");
                };
                let mut off = value_start + 1;
                for item in inner.split(',') {
                    let (item_off, item_start) = (off, skip_ws(line, off));
                    off += item.len() + 1;
                    if item.trim().is_empty() && inner.trim().is_empty() {
                        break; // `{}`
                    }
                    let Some((k, v)) = item.split_once('=') else {
                        return fail(ln, raw, item_start, "expected `param = number` in the inline table");
                    };
                    let v_start = skip_ws(line, item_off + k.len() + 1);
                    p.entry(
                        effect,
                        e_pos,
                        k.trim(),
                        pos(ln, raw, item_start),
                        v.trim(),
                        pos(ln, raw, v_start),
                    )?;
                }
            }
            (None, _) => {
                return fail(
                    ln,
                    raw,
                    start,
                    format!(
                        "`{}` is outside any [effect_id] section: put it under `[effect_id]` or write \
                         `effect_id.param = number`",
                        body[..eq].trim()
                    ),
                );
            }
        }
    }
    Ok(p.file)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(line: usize, col: usize) -> Pos {
        Pos { line, col }
    }

    #[test]
    fn sections_dotted_keys_and_inline_tables() {
        let f = parse_effect_file(
            "# head\n\
             a.x = 1 # c\n\
             a.y = -2.5e-1\n\
             b = { p = 1_000, q = 0x10 }\n\
             [ c ]\n\
             r = +inf\n\
             \t s = 3.\u{20}\n\
             [d]\n",
        );
        // `3.` is not a TOML float.
        let e = f.unwrap_err();
        assert_eq!((e.at, e.msg.contains("expected a number")), (at(7, 7), true), "{e:?}");

        let f = parse_effect_file(
            "a.x = 1 # c\na.y = -2.5e-1\nb = { p = 1_000, q = 0x10 }\n[ c ]\nr = +inf\n\t s = 3.0\n[d]\n",
        )
        .unwrap();
        let ids: Vec<(&str, Pos)> = f.sections.iter().map(|s| (s.id.as_str(), s.at)).collect();
        assert_eq!(ids, [("a", at(1, 1)), ("b", at(3, 1)), ("c", at(4, 3)), ("d", at(7, 2))]);
        let got: Vec<(&str, &str, f64)> =
            f.entries.iter().map(|e| (e.effect.as_str(), e.param.as_str(), e.value)).collect();
        assert_eq!(
            got,
            [
                ("a", "x", 1.0),
                ("a", "y", -0.25),
                ("b", "p", 1000.0),
                ("b", "q", 16.0),
                ("c", "r", f64::INFINITY),
                ("c", "s", 3.0)
            ]
        );
        let s = &f.entries[5];
        assert_eq!((s.effect_at, s.param_at, s.value_at), (at(4, 3), at(6, 3), at(6, 7)));
        let q = &f.entries[3];
        assert_eq!((q.param_at, q.value_at), (at(3, 18), at(3, 22)));
        assert_eq!(f.locate("c", Some("s")), Some(at(6, 7)));
        assert_eq!(f.locate("d", Some("zz")), Some(at(7, 2)));
        assert_eq!(f.locate("zz", None), None);
    }

    #[test]
    fn errors_are_located() {
        let err = |t: &str| parse_effect_file(t).unwrap_err();
        let e = err("delay_s = 0.01\n");
        assert_eq!(e.at, at(1, 1));
        assert!(e.msg.contains("[effect_id]"), "{}", e.msg);
        assert_eq!(err("[a]\nx = \"long\"\n").at, at(2, 5));
        assert_eq!(err("[a]\nx = 1\n[a]\n").at, at(3, 2));
        assert_eq!(err("a.x = 1\n[a]\n").at, at(2, 2));
        assert_eq!(err("[a]\nx = 1\nx = 2\n").at, at(3, 1));
        assert_eq!(err("[a]\nb.x = 1\n").at, at(2, 1));
        assert_eq!(err("[a\n").at, at(1, 1));
        assert_eq!(err("[[a]]\n").at, at(1, 1));
        assert_eq!(err("[a]\nx\n").at, at(2, 1));
        assert_eq!(err("[a] x\n").at, at(1, 4));
        assert_eq!(err("[a]\nx = 1 2\n").at, at(2, 5));
        assert_eq!(err("b = { p = 1, q }\n").at, at(1, 14));
        // Columns count characters.
        assert_eq!(err("[a] # é\nx = é\n").at, at(2, 5));
    }

    #[test]
    fn numbers_follow_toml() {
        for (s, v) in
            [("0", 0.0), ("-0.5", -0.5), ("1_000.25", 1000.25), ("6.626e-34", 6.626e-34), ("0o17", 15.0)]
        {
            assert_eq!(parse_number(s), Some(v), "{s}");
        }
        assert!(parse_number("nan").is_some_and(f64::is_nan));
        for s in ["", "1.", ".5", "01", "1__0", "_1", "1e", "+0x10", "true", "\"1\"", "1 2"] {
            assert_eq!(parse_number(s), None, "{s}");
        }
        // The same f64 a TOML reader gives (narrowed to f32 by the caller).
        assert_eq!(parse_number("0.1"), Some(0.1));
    }
}
