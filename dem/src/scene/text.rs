//! The scene's text before it is read: numbers that are not finite, and
//! the values `--set` puts over it.

use super::{Ctx, SceneError};

/// No number of a scene may be NaN or infinite (TOML writes them `nan`,
/// `inf`): refused where written, naming the key, before anything is built
/// from it. The text has parsed as TOML, so outside strings and comments
/// these words can only be values.
pub(super) fn refuse_non_finite(ctx: &Ctx) -> Result<(), SceneError> {
    let mut offset = 0;
    let mut key = String::new();
    for line in ctx.text.split_inclusive('\n') {
        let code = strip_strings_and_comment(line);
        if code.trim_start().starts_with('[') && !code.contains('=') {
            offset += line.len();
            continue;
        }
        // Keys of the inline tables the value sits in ("contact.skin").
        let mut tables: Vec<String> = Vec::new();
        let parts = code.split('=').count();
        for (i, part) in code.split('=').enumerate() {
            // The last part is all value; the others end with the next key.
            let next_key = if i + 1 == parts {
                String::new()
            } else {
                part.trim_end()
                    .rsplit(|c: char| c.is_whitespace() || ",{[".contains(c))
                    .next()
                    .unwrap_or("")
                    .to_string()
            };
            let value = if i == 0 {
                ""
            } else {
                &part[..part.trim_end().len() - next_key.len()]
            };
            let bad = value
                .split(|c: char| c.is_whitespace() || ",[]{}".contains(c))
                .find(|w| matches!(w.trim_start_matches(['+', '-']), "nan" | "inf"));
            if let Some(word) = bad {
                let path: Vec<&str> = tables
                    .iter()
                    .map(String::as_str)
                    .chain([key.as_str()])
                    .collect();
                return ctx.err(
                    offset..offset + line.len(),
                    format!(
                        "{} = {word}: every number of a scene must be finite",
                        path.join(".")
                    ),
                );
            }
            if i > 0 && value.trim_start().starts_with('{') {
                tables.push(key.clone());
            }
            for _ in 0..value.matches('}').count() {
                tables.pop();
            }
            if !next_key.is_empty() {
                key = next_key;
            }
        }
        offset += line.len();
    }
    Ok(())
}

/// A line of TOML with its strings blanked and its comment cut.
fn strip_strings_and_comment(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    let mut quote: Option<char> = None;
    let mut escaped = false;
    for c in line.chars() {
        match quote {
            Some(q) => {
                if c == q && !escaped {
                    quote = None;
                }
                escaped = c == '\\' && !escaped && q == '"';
                out.push(' ');
            }
            None if c == '"' || c == '\'' => {
                quote = Some(c);
                out.push(' ');
            }
            None if c == '#' => break,
            None => out.push(c),
        }
    }
    out
}

/// Sets one `section.key=value` of `--set` in a scene's table.
pub(super) fn set_override(table: &mut toml::Table, o: &str) -> Result<(), String> {
    let (path, value) = o
        .split_once('=')
        .ok_or_else(|| format!("--set {o}: expected section.key=value"))?;
    let keys: Vec<&str> = path.trim().split('.').map(str::trim).collect();
    if keys.len() < 2 || keys.iter().any(|k| k.is_empty()) {
        return Err(format!("--set {o}: expected section.key=value"));
    }
    let value = value.trim();
    let value = format!("v = {value}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(value.to_string()));
    let (last, sections) = keys.split_last().expect("two keys or more");
    let mut at = table;
    for k in sections {
        let entry = at
            .entry(k.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        at = entry.as_table_mut().ok_or_else(|| {
            format!("--set {o}: {k} is not a section (lists of bodies cannot be set)")
        })?;
    }
    at.insert(last.to_string(), value);
    Ok(())
}
