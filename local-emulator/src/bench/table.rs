//! Benchmark output: an aligned table on stdout and the same rows as CSV.

use anyhow::{Context, Result};
use std::path::Path;

/// Rows of string cells under a header.
pub struct Table {
    pub title: String,
    pub header: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

impl Table {
    pub fn new(title: &str, header: &[&str]) -> Table {
        Table {
            title: title.to_string(),
            header: header.iter().map(|h| h.to_string()).collect(),
            rows: Vec::new(),
        }
    }

    pub fn push(&mut self, row: Vec<String>) {
        self.rows.push(row);
    }

    /// Prints the table with aligned columns.
    pub fn print(&self) {
        let mut widths: Vec<usize> = self.header.iter().map(String::len).collect();
        for row in &self.rows {
            for (w, cell) in widths.iter_mut().zip(row) {
                *w = (*w).max(cell.len());
            }
        }
        println!("\n{}", self.title);
        let line = |cells: &[String]| {
            let padded: Vec<String> = cells
                .iter()
                .zip(&widths)
                .map(|(c, w)| format!("{c:>w$}"))
                .collect();
            println!("  {}", padded.join("  "));
        };
        line(&self.header);
        for row in &self.rows {
            line(row);
        }
    }

    /// The table as Markdown (title as a paragraph, then a pipe table), for docs.
    pub fn markdown(&self) -> String {
        let row = |cells: &[String]| format!("| {} |\n", cells.join(" | "));
        let mut out = format!("{}\n\n", self.title);
        out += &row(&self.header);
        out += &row(&vec!["---".to_string(); self.header.len()]);
        for r in &self.rows {
            out += &row(r);
        }
        out
    }

    /// Appends the table to `path` as CSV (one `table` column naming it).
    pub fn append_csv(&self, path: &Path) -> Result<()> {
        use std::io::Write;
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .with_context(|| format!("cannot write {}", path.display()))?;
        let escape = |s: &str| {
            if s.contains([',', '"']) {
                format!("\"{}\"", s.replace('"', "\"\""))
            } else {
                s.to_string()
            }
        };
        writeln!(
            file,
            "table,{}",
            self.header
                .iter()
                .map(|h| escape(h))
                .collect::<Vec<_>>()
                .join(",")
        )?;
        for row in &self.rows {
            writeln!(
                file,
                "{},{}",
                escape(&self.title),
                row.iter().map(|c| escape(c)).collect::<Vec<_>>().join(",")
            )?;
        }
        Ok(())
    }
}

/// Formats a ratio or a value with 3 significant decimals.
pub fn f3(v: f64) -> String {
    format!("{v:.3}")
}
