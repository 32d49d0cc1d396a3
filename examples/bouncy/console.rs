//! Standard output that goes quiet when its reader has gone.
//!
//! `println!` panics when standard output is a closed pipe (`bouncy | head -1`: exit status
//! 101 and a backtrace). [`Console`] stops printing instead and the run carries on, so that
//! its files are still written and the exit status still says how the run went.

use std::fmt::Display;
use std::io::{self, ErrorKind, Write};

/// Lines of text for the user, on standard output (or any writer, in tests).
#[derive(Debug)]
pub struct Console<W: Write> {
    out: W,
    open: bool,
}

impl Console<io::Stdout> {
    /// The process's standard output.
    pub fn stdout() -> Self {
        Console::new(io::stdout())
    }
}

impl<W: Write> Console<W> {
    /// Lines into `out`.
    pub fn new(out: W) -> Self {
        Console { out, open: true }
    }

    /// The writer, for a test to read what was written.
    #[cfg(test)]
    pub fn into_inner(self) -> W {
        self.out
    }

    /// Writes `text` and a newline. After a failed write nothing more is written: a broken
    /// pipe silently (the reader left), any other error with one warning on standard error.
    pub fn line(&mut self, text: impl Display) {
        if !self.open {
            return;
        }
        if let Err(error) = writeln!(self.out, "{text}").and_then(|()| self.out.flush()) {
            self.open = false;
            if error.kind() != ErrorKind::BrokenPipe {
                eprintln!(
                    "warning: cannot write to standard output ({error}); carrying on without it"
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pipe whose reader leaves after `capacity` bytes.
    struct ClosingPipe {
        written: Vec<u8>,
        capacity: usize,
        attempts: usize,
    }

    impl Write for ClosingPipe {
        fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
            self.attempts += 1;
            if self.written.len() + bytes.len() > self.capacity {
                return Err(io::Error::from(ErrorKind::BrokenPipe));
            }
            self.written.extend_from_slice(bytes);
            Ok(bytes.len())
        }

        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_broken_pipe_silences_the_console_without_panicking() {
        let pipe = ClosingPipe {
            written: Vec::new(),
            capacity: 6,
            attempts: 0,
        };
        let mut console = Console::new(pipe);
        console.line("first");
        assert!(console.open);
        console.line("second");
        assert!(!console.open);
        let attempts = console.out.attempts;
        console.line("third");
        assert_eq!(
            console.out.attempts, attempts,
            "no write after the pipe broke"
        );
        assert_eq!(console.out.written, b"first\n");
    }
}
