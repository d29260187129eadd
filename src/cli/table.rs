//! Result tables: one look for every command, fitted to the terminal's width (cells wrap on a
//! narrow terminal; piped output keeps whole rows, for grep and diff).

use comfy_table::{presets, CellAlignment, ContentArrangement, Table};

/// A table with `header`; the first `left` columns are left-aligned (names), the rest right
/// (numbers).
pub fn new(header: &[&str], left: usize) -> Table {
    let mut t = Table::new();
    t.load_preset(presets::NOTHING)
        .set_content_arrangement(ContentArrangement::Dynamic)
        .set_header(header.to_vec());
    for (i, col) in t.column_iter_mut().enumerate() {
        col.set_cell_alignment(if i < left {
            CellAlignment::Left
        } else {
            CellAlignment::Right
        });
    }
    t
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_narrow_terminal_wraps_cells_instead_of_rows() {
        let mut t = super::new(&["term", "a long column header", "another long header"], 1);
        t.add_row(vec!["N", "0.03846 (0.818)", "0.02899* (0.754)"]);
        t.set_width(40);
        let text = t.to_string();
        assert!(text.lines().all(|l| l.chars().count() <= 40), "{text}");
        assert!(text.contains("0.818") && text.contains("0.754"), "{text}");
    }
}
