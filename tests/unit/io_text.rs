//! Tests of `src/io/text.rs`.

use destair::io::text::*;

#[test]
fn tokens_lines_and_ends() {
    let mut c = TextCursor::new(b"a b\r\n\n  c\td\n", 1);
    assert_eq!(c.inline_token(), Some(&b"a"[..]));
    assert_eq!(c.inline_token(), Some(&b"b"[..]));
    assert_eq!(c.inline_token(), None);
    assert!(c.finish_line());
    assert_eq!(c.line(), 2);
    assert_eq!(c.token(), Some(&b"c"[..]));
    assert_eq!(c.line(), 3);
    assert!(!c.finish_line());
    assert_eq!(c.rest_of_line(), b"d");
    assert!(c.at_end());
    assert_eq!(c.token(), None);
}
