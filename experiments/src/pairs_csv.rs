//! Reading triangle pairs from CSV: rows of at least 18 numbers.

use crate::error::{CliError, CliResult};
use dem::distance::Triangle;
use glam::DVec3;

/// Parses rows of at least 18 numbers (the first triangle's three vertices,
/// then the second's; further columns are ignored). Blank lines and lines
/// starting with `#` are skipped. `source` names the input in errors.
pub fn parse_pairs(text: &str, source: &str) -> CliResult<Vec<(Triangle, Triangle)>> {
    let mut pairs = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line_no = i + 1;
        let trimmed = line.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = trimmed.split(',').collect();
        if fields.len() < 18 {
            return Err(CliError::input(format!(
                "{source}:{line_no}: expected at least 18 numbers, found {} fields",
                fields.len()
            )));
        }
        let mut v = [0.0f64; 18];
        for (k, f) in fields.iter().take(18).enumerate() {
            let x: f64 = f.trim().parse().map_err(|_| {
                CliError::input(format!(
                    "{source}:{line_no}: field {} is not a number: `{}`",
                    k + 1,
                    f.trim()
                ))
            })?;
            if !x.is_finite() {
                return Err(CliError::input(format!(
                    "{source}:{line_no}: field {} is not finite: `{}`",
                    k + 1,
                    f.trim()
                )));
            }
            v[k] = x;
        }
        let p = |j: usize| DVec3::new(v[3 * j], v[3 * j + 1], v[3 * j + 2]);
        pairs.push(([p(0), p(1), p(2)], [p(3), p(4), p(5)]));
    }
    Ok(pairs)
}

#[cfg(test)]
mod tests {
    use super::*;

    const ROW: &str = "0,0,0,1,0,0,0,1,0,0,0,1,1,0,1,0,1,1";

    #[test]
    fn parses_rows_and_skips_comments() {
        let text = format!("# header\n\n{ROW},extra,0.5\n");
        let pairs = parse_pairs(&text, "in.csv").unwrap();
        assert_eq!(pairs.len(), 1);
        assert_eq!(pairs[0].1[1], DVec3::new(1.0, 0.0, 1.0));
    }

    #[test]
    fn errors_name_line_and_field() {
        let text = format!("{ROW}\n0,0,0,1,0,0,0,x,0,0,0,1,1,0,1,0,1,1\n");
        let e = parse_pairs(&text, "in.csv").unwrap_err();
        assert_eq!(e.exit_code(), 2);
        assert_eq!(e.to_string(), "in.csv:2: field 8 is not a number: `x`");
        let e = parse_pairs("1,2,3\n", "in.csv").unwrap_err();
        assert!(
            e.to_string().starts_with("in.csv:1: expected at least 18"),
            "{e}"
        );
        let e = parse_pairs("0,0,0,1,0,0,0,1,0,0,0,1,1,0,1,0,1,NaN", "s").unwrap_err();
        assert!(e.to_string().contains("field 18 is not finite"), "{e}");
    }
}
