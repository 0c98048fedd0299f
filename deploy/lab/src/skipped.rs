//! Outside data is read, not trusted: a record that is malformed or impossible is skipped and
//! counted, and the first few are kept with their line numbers to say what was wrong.

/// Lines skipped while reading: how many, and the first few with their problem.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SkippedLines {
    pub count: usize,
    /// The first [`SkippedLines::KEPT`] skipped lines: 1-based number and problem.
    pub first: Vec<(usize, String)>,
}

impl SkippedLines {
    pub const KEPT: usize = 3;

    /// Count line `line` (1-based) as skipped for `problem`.
    pub fn add(&mut self, line: usize, problem: String) {
        self.count += 1;
        if self.first.len() < Self::KEPT {
            self.first.push((line, problem));
        }
    }
}

impl std::fmt::Display for SkippedLines {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} line(s) skipped", self.count)?;
        for (i, (line, problem)) in self.first.iter().enumerate() {
            let sep = if i == 0 { " (first: " } else { "; " };
            write!(f, "{sep}line {line}: {problem}")?;
        }
        if !self.first.is_empty() {
            write!(f, ")")?;
        }
        Ok(())
    }
}
