//! A byte cursor over text formats (PLY ASCII, STL ASCII, OBJ) that tracks line numbers.

/// Position in a text buffer; lines count from 1.
pub struct TextCursor<'a> {
    data: &'a [u8],
    pos: usize,
    line: usize,
}

#[inline]
fn is_inline_space(b: u8) -> bool {
    b == b' ' || b == b'\t' || b == b'\r' || b == 0x0b || b == 0x0c
}

impl<'a> TextCursor<'a> {
    /// A cursor at `data[0]`, which is on line `first_line`.
    pub fn new(data: &'a [u8], first_line: usize) -> Self {
        Self {
            data,
            pos: 0,
            line: first_line,
        }
    }

    /// Current line number (1-based).
    pub fn line(&self) -> usize {
        self.line
    }

    /// True when nothing but whitespace remains.
    pub fn at_end(&mut self) -> bool {
        self.skip_space();
        self.pos >= self.data.len()
    }

    /// Skips whitespace including line breaks.
    pub fn skip_space(&mut self) {
        while let Some(&b) = self.data.get(self.pos) {
            if b == b'\n' {
                self.line += 1;
            } else if !is_inline_space(b) {
                break;
            }
            self.pos += 1;
        }
    }

    /// Skips spaces and tabs but stops at a line break.
    pub fn skip_inline_space(&mut self) {
        while self.data.get(self.pos).is_some_and(|&b| is_inline_space(b)) {
            self.pos += 1;
        }
    }

    /// The next token on the current line, or `None` at a line break or the end.
    pub fn inline_token(&mut self) -> Option<&'a [u8]> {
        self.skip_inline_space();
        let start = self.pos;
        while self
            .data
            .get(self.pos)
            .is_some_and(|&b| b != b'\n' && !is_inline_space(b))
        {
            self.pos += 1;
        }
        (self.pos > start).then(|| &self.data[start..self.pos])
    }

    /// The next token, crossing line breaks; `None` at the end.
    pub fn token(&mut self) -> Option<&'a [u8]> {
        self.skip_space();
        self.inline_token()
    }

    /// Whether only spaces remain on the current line (then moves past its break).
    pub fn finish_line(&mut self) -> bool {
        self.skip_inline_space();
        match self.data.get(self.pos) {
            None => true,
            Some(b'\n') => {
                self.pos += 1;
                self.line += 1;
                true
            }
            Some(_) => false,
        }
    }

    /// The rest of the current line (without its break), moving past the break.
    pub fn rest_of_line(&mut self) -> &'a [u8] {
        let start = self.pos;
        while self.data.get(self.pos).is_some_and(|&b| b != b'\n') {
            self.pos += 1;
        }
        let line = &self.data[start..self.pos];
        if self.pos < self.data.len() {
            self.pos += 1;
            self.line += 1;
        }
        line.strip_suffix(b"\r").unwrap_or(line)
    }
}

/// Shows a token in an error message, shortened and with invalid UTF-8 replaced.
pub fn show(token: &[u8]) -> String {
    let s = String::from_utf8_lossy(&token[..token.len().min(40)]).into_owned();
    if token.len() > 40 {
        format!("{s}...")
    } else {
        s
    }
}

/// Parses a decimal float token (also `nan`/`inf`, which callers then reject as non-finite).
pub fn parse_f64(token: &[u8]) -> Option<f64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}

/// Parses a decimal integer token.
pub fn parse_i64(token: &[u8]) -> Option<i64> {
    std::str::from_utf8(token).ok()?.parse().ok()
}
