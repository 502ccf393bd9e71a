//! The time-by-section table of `tridem run` and `tridem scaling`.

use dem::timing::SectionTimes;

/// One row of the table: a section, its seconds, and whether it is a part of
/// the row above it (the phases of contact detection).
pub struct SectionRow {
    pub name: String,
    pub seconds: f64,
    pub part: bool,
}

impl SectionRow {
    /// The row's key in JSON output.
    pub fn key(&self) -> String {
        self.name.replace(' ', "_")
    }
}

/// Integration, then each effect in pipeline order, the contact effect
/// followed by its parts: detection's three phases and the contact laws
/// (what is left of the effect's time).
pub fn section_rows(t: &SectionTimes) -> Vec<SectionRow> {
    let row = |name: &str, seconds: f64, part: bool| SectionRow {
        name: name.to_string(),
        seconds,
        part,
    };
    let mut rows = vec![row("integration", t.integration, false)];
    for &(name, seconds) in &t.effects {
        rows.push(row(name, seconds, false));
        if Some(name) == t.detecting_effect {
            let d = &t.detection;
            rows.push(row("triangle update", d.triangle_update, true));
            rows.push(row("broad phase", d.broad_phase, true));
            rows.push(row("narrow phase", d.narrow_phase, true));
            rows.push(row("contact laws", (seconds - d.total()).max(0.0), true));
        }
    }
    rows
}

/// The row's label, parts indented under their section.
pub fn label(row: &SectionRow) -> String {
    if row.part {
        format!("  {}", row.name)
    } else {
        row.name.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem::timing::DetectionTimes;

    #[test]
    fn contact_is_broken_down_into_its_phases_and_laws() {
        let t = SectionTimes {
            integration: 1.0,
            effects: vec![("gravity", 0.5), ("contact", 10.0), ("friction", 2.0)],
            detection: DetectionTimes {
                triangle_update: 1.0,
                broad_phase: 0.5,
                narrow_phase: 6.0,
                narrow_phase_busy: 11.0,
            },
            detecting_effect: Some("contact"),
        };
        let rows = section_rows(&t);
        let names: Vec<_> = rows.iter().map(|r| r.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "integration",
                "gravity",
                "contact",
                "triangle update",
                "broad phase",
                "narrow phase",
                "contact laws",
                "friction"
            ]
        );
        assert_eq!(rows[6].seconds, 2.5);
        // The top-level rows add up to all the stepping time, the parts to their section.
        let top: f64 = rows.iter().filter(|r| !r.part).map(|r| r.seconds).sum();
        assert_eq!(top, t.total());
        let parts: f64 = rows.iter().filter(|r| r.part).map(|r| r.seconds).sum();
        assert_eq!(parts, 10.0);
        assert_eq!(rows[3].key(), "triangle_update");
    }
}
