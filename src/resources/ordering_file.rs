//! The ordering file: a fill-reducing ordering made outside the library
//! (METIS or Scotch run by hand, an ordering another library used),
//! handed to every back end as [`FillOrdering::Given`].
//!
//! # Format
//!
//! Text (UTF-8): the unknowns of the problem in the order they are to be
//! eliminated, 0-based, entry `i` being the unknown eliminated `i`-th. For
//! a mesh the unknowns are its vertices (in the mesh file's order); for a
//! general problem `min ‖AX − C‖ s.t. BX = D`, the columns of `A`.
//!
//! - Entries are separated by whitespace and/or commas, so one entry per
//!   line, one line of entries and a JSON array (`[3, 0, 2, 1]`, the whole
//!   file between one pair of brackets) are all read.
//! - `#` starts a comment that runs to the end of its line.
//!
//! That it is a permutation of the problem's unknowns is checked against
//! the problem when the factorisation is planned
//! ([`crate::backend::ordering::FactorPlan::new`]), which names the first
//! entry at fault; this reader names the line of a word that is not an
//! index.
//!
//! # Memory
//!
//! A read is whole or refused. A regular file's size is checked against
//! the budget first, at [`ORDERING_BYTES_PER_FILE_BYTE`] per byte (its
//! text, and at most one 8-byte index per two bytes of it) on top of what
//! the process already holds; a stream (a
//! pipe, a device) is read up to the size that allows, and one that
//! reaches it is refused, whatever its first part holds.

use std::io::Read;
use std::path::Path;
use std::sync::Arc;

use super::FillOrdering;
use crate::error::{Error, ProblemError};
use crate::limits::MemoryBudget;

/// Bytes of memory per byte of an ordering file: the text (1) and the
/// indices (8 bytes per index; an index with its separator takes at least
/// two bytes of text, so at most 4 per byte). The reader holds nothing
/// else that grows with the file: the indices are counted first and
/// written into one allocation of exactly that many
/// ([`parse_ordering`]).
pub const ORDERING_BYTES_PER_FILE_BYTE: u64 = 5;

fn invalid(message: String) -> Error {
    ProblemError::InvalidArgument { message }.into()
}

/// Reads the ordering file `path` ([module docs](self)) within `budget`,
/// as [`FillOrdering::Given`].
pub fn read_ordering_file(path: &Path, budget: MemoryBudget) -> Result<FillOrdering, Error> {
    let io = |e| Error::io(path, e);
    let file = crate::input::open_input(path).map_err(io)?;
    let per_byte = ORDERING_BYTES_PER_FILE_BYTE;
    let name = format!("the ordering file {}", path.display());
    let too_large = |detail| ProblemError::TooLarge { detail };
    let cap = crate::limits::file_read_cap(&file, &name, budget, per_byte).map_err(too_large)?;
    if let Some(size) = file
        .metadata()
        .ok()
        .filter(|m| m.is_file())
        .map(|m| m.len())
    {
        // What the process already holds counts too (the budget is of the
        // whole run).
        budget
            .check_on_top(size.saturating_mul(per_byte), || {
                format!("{name} ({}) would need", crate::limits::format_bytes(size))
            })
            .map_err(too_large)?;
    }
    let mut bytes = Vec::new();
    file.take(cap.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > cap {
        let detail = crate::limits::beyond_the_cap(budget, &name, cap, "", per_byte, "reading");
        return Err(ProblemError::TooLarge { detail }.into());
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        invalid(format!(
            "the ordering file {} is not UTF-8 text (byte {})",
            path.display(),
            e.utf8_error().valid_up_to()
        ))
    })?;
    let order = parse_ordering(&text)
        .map_err(|message| invalid(format!("the ordering file {}: {message}", path.display())))?;
    Ok(FillOrdering::Given(order))
}

/// The words of an ordering file's text with their lines (1-based):
/// separated by whitespace and commas, `#` comments removed.
fn words(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().flat_map(|(i, line)| {
        let code = line.split('#').next().unwrap_or("");
        code.split(|c: char| c.is_whitespace() || c == ',')
            .filter(|w| !w.is_empty())
            .map(move |w| (i + 1, w))
    })
}

/// The indices of an ordering file's text ([module docs](self)), or what
/// is wrong and on which line (1-based). Two passes over the text: the
/// first counts the words, the second parses them into one allocation of
/// that length (8 bytes per word, beside the text; nothing per word
/// besides).
pub(crate) fn parse_ordering(text: &str) -> Result<Arc<[usize]>, String> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let count = words(text).count();
    let bracketed = words(text).next().is_some_and(|(_, w)| w.starts_with('['));
    let mut order: Arc<[usize]> = std::iter::repeat_n(0, count).collect();
    let slots = Arc::get_mut(&mut order).ok_or("the ordering is shared")?;
    let mut filled = 0;
    for (place, (line, word)) in words(text).enumerate() {
        let Some(word) = unbracketed(word, line, bracketed, place, count)? else {
            continue;
        };
        slots[filled] = word.parse::<usize>().map_err(|_| {
            format!(
                "line {line}: {:?} is not an index (a non-negative integer)",
                crate::error::excerpt(word)
            )
        })?;
        filled += 1;
    }
    if filled == 0 {
        return Err("no index: an ordering lists every unknown once".into());
    }
    Ok(if filled == count {
        order
    } else {
        Arc::from(&order[..filled])
    })
}

/// The word at `place` of `count` with one pair of brackets around the
/// whole list removed (a JSON array; `bracketed`: the first word opens
/// with `[`), written apart from (`None`: nothing is left) or against the
/// first and last entries; a bracket anywhere else is an error naming its
/// line.
fn unbracketed(
    word: &str,
    line: usize,
    bracketed: bool,
    place: usize,
    count: usize,
) -> Result<Option<&str>, String> {
    let mut rest = word;
    if bracketed && place == 0 {
        rest = &rest[1..];
    }
    if bracketed && place + 1 == count {
        rest = rest.strip_suffix(']').ok_or_else(|| {
            format!(
                "line {line}: a list that opens with '[' must close with ']' after its last index"
            )
        })?;
    }
    if rest.contains(['[', ']']) {
        return Err(format!(
            "line {line}: {:?} is not an index (brackets only around the whole list)",
            crate::error::excerpt(word)
        ));
    }
    Ok(Some(rest).filter(|r| !r.is_empty()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_per_line_one_line_and_a_json_array_read_alike() {
        let expected = vec![3, 0, 2, 1];
        for text in [
            "3\n0\n2\n1\n",
            "3 0 2 1",
            "[3, 0, 2, 1]",
            "[ 3,0,\n 2 , 1 ]\n",
            "\u{feff}# from METIS\n3 0  # first two\n2\t1\n",
        ] {
            assert_eq!(
                parse_ordering(text).map(|o| o.to_vec()),
                Ok(expected.clone()),
                "{text:?}"
            );
        }
    }

    #[test]
    fn a_word_that_is_not_an_index_is_named_with_its_line() {
        let e = parse_ordering("0\n1\n-2\n3").unwrap_err();
        assert!(e.contains("line 3") && e.contains("\"-2\""), "{e}");
        let e = parse_ordering("0 1.5").unwrap_err();
        assert!(e.contains("line 1") && e.contains("1.5"), "{e}");
        let e = parse_ordering("[0, 1").unwrap_err();
        assert!(e.contains("']'"), "{e}");
        let e = parse_ordering("0 [1] 2").unwrap_err();
        assert!(e.contains("[1]"), "{e}");
        assert!(parse_ordering("# nothing\n").is_err());
        assert!(parse_ordering("[]").is_err());
    }

    /// A huge word is quoted by its first 80 characters and `…`: a 20 MB
    /// word gave a 20 MB one-line error on aa82d57.
    #[test]
    fn a_huge_word_is_quoted_by_its_beginning() {
        let word = "x".repeat(20 << 20);
        let e = parse_ordering(&format!("0 {word} 2")).unwrap_err();
        assert!(e.len() < 200, "{} bytes", e.len());
        assert!(e.contains(&format!("\"{}…\"", "x".repeat(80))), "{e}");
        let e = parse_ordering(&format!("0 [{word}] 2")).unwrap_err();
        assert!(e.len() < 200 && e.contains("brackets"), "{} bytes", e.len());
    }

    #[test]
    fn a_file_beyond_the_budget_is_refused_before_it_is_read() {
        let dir = std::env::temp_dir().join(format!("lse-ordering-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("order.txt");
        let text: String = (0..1000).map(|i| format!("{i}\n")).collect();
        std::fs::write(&path, &text).unwrap();
        let small = MemoryBudget::bytes(text.len() as u64 * 4);
        let refused = read_ordering_file(&path, small).unwrap_err();
        assert!(
            matches!(refused, Error::Problem(ProblemError::TooLarge { .. })),
            "{refused}"
        );
        let read = read_ordering_file(&path, MemoryBudget::bytes(1 << 30)).unwrap();
        match read {
            FillOrdering::Given(order) => assert_eq!(&order[..], &(0..1000).collect::<Vec<_>>()),
            other => panic!("{other:?}"),
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
