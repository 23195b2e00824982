//! The exit codes: their one definition. `main` ends with them, `dbbcal --help` prints
//! [`help_text`], and the README's table is [`markdown_table`] (tests/e2e/docs.rs checks it
//! word for word).

/// How a `dbbcal` process ends. 2 is clap's own (a command-line usage error); the interrupted
/// codes are 128 + the signal, not a variant (see [`INTERRUPTED`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// Every bar processed; the output is in place.
    Success,
    /// Any other error.
    Other,
    /// A command-line usage error, found by clap before anything is read.
    Usage,
    /// Unusable input or configuration, or an output location dbbcal may not write.
    UnusableInput,
    /// Some bars failed; the others are in the output.
    SomeBarsFailed,
    /// No bar succeeded; nothing written.
    NoBarSucceeded,
    /// Another run holds the output's lock.
    OutputBusy,
}

impl Exit {
    /// Every code, in the order the tables list them.
    pub const ALL: [Exit; 7] = [
        Exit::Success,
        Exit::Other,
        Exit::Usage,
        Exit::UnusableInput,
        Exit::SomeBarsFailed,
        Exit::NoBarSucceeded,
        Exit::OutputBusy,
    ];

    /// The process's exit status.
    pub fn code(self) -> u8 {
        match self {
            Exit::Success => 0,
            Exit::Other => 1,
            Exit::Usage => 2,
            Exit::UnusableInput => 3,
            Exit::SomeBarsFailed => 4,
            Exit::NoBarSucceeded => 5,
            Exit::OutputBusy => 6,
        }
    }

    /// What the code tells the user, one sentence for `--help` and the README.
    pub fn meaning(self) -> &'static str {
        match self {
            Exit::Success => "every bar processed; the output is in place",
            Exit::Other => {
                "another error (e.g. the output could not be written, or the analysis was killed: \
                 SIGKILL, out of memory); the previous output is unchanged"
            }
            Exit::Usage => "command-line usage error (clap); nothing read or written",
            Exit::UnusableInput => {
                "unusable input or configuration, or an output location dbbcal may not write: one \
                 line names the file, column, key, rows or path; refused before any output is \
                 touched"
            }
            Exit::SomeBarsFailed => {
                "some bars failed: the others are in the output, the failures in `summary.json` → \
                 `failed_bars`"
            }
            Exit::NoBarSucceeded => {
                "no bar succeeded: nothing written, the previous output unchanged; the line gives \
                 each bar's reason"
            }
            Exit::OutputBusy => {
                "another dbbcal run is writing the same output (its lock is held); nothing done"
            }
        }
    }
}

impl From<Exit> for std::process::ExitCode {
    fn from(exit: Exit) -> Self {
        std::process::ExitCode::from(exit.code())
    }
}

/// The codes of an interrupted run (128 + SIGINT, 128 + SIGTERM) and their meaning.
pub const INTERRUPTED: (&str, &str) = (
    "130, 143",
    "interrupted by Ctrl-C or SIGTERM: the partial folder removed, the previous output unchanged",
);

/// The table in the README: `| code | meaning |`, one row a code.
pub fn markdown_table() -> String {
    let mut table = String::from("| code | meaning |\n|---|---|\n");
    let rows = Exit::ALL
        .iter()
        .map(|e| (e.code().to_string(), e.meaning()))
        .chain(std::iter::once((INTERRUPTED.0.to_string(), INTERRUPTED.1)));
    for (code, meaning) in rows {
        table.push_str(&format!("| {code} | {meaning} |\n"));
    }
    table
}

/// The `Exit codes:` part of `dbbcal --help`: the same rows, the meanings wrapped to fit 100
/// columns (backquotes dropped).
pub fn help_text() -> String {
    let mut text = String::from("Exit codes:\n");
    let rows = Exit::ALL
        .iter()
        .map(|e| (e.code().to_string(), e.meaning()))
        .chain(std::iter::once((INTERRUPTED.0.to_string(), INTERRUPTED.1)));
    for (code, meaning) in rows {
        let mut line = format!("  {code:<9}");
        for word in meaning.replace('`', "").split_whitespace() {
            if line.len() + 1 + word.len() > 100 {
                text.push_str(line.trim_end());
                text.push('\n');
                line = " ".repeat(11);
            } else if !line.ends_with(' ') {
                line.push(' ');
            }
            line.push_str(word);
        }
        text.push_str(&line);
        text.push('\n');
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_distinct_and_every_code_is_in_both_tables() {
        let mut codes: Vec<u8> = Exit::ALL.iter().map(|e| e.code()).collect();
        codes.dedup();
        assert_eq!(codes, [0, 1, 2, 3, 4, 5, 6]);
        let (table, help) = (markdown_table(), help_text());
        for e in Exit::ALL {
            assert!(table.contains(&format!("| {} | {} |", e.code(), e.meaning())));
            assert!(help.contains(&format!("  {:<9}", e.code())), "{help}");
        }
        assert!(help.lines().all(|l| l.chars().count() <= 100), "{help}");
    }
}
