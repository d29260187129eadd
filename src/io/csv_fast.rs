//! The fast path of CSV input: plain numeric lines parsed straight from the bytes (a memory map
//! of the file, or blocks a reader thread decompresses), in parallel chunks for a mapped file.
//!
//! It parses only what it can parse exactly as the csv crate and `str::parse::<f64>` would (the
//! reference path in [`super::csv_table`]): lines of `fields` comma-separated cells, ASCII spaces
//! or tabs around numbers, `\n` or `\r\n` line ends, blank lines and `#` comment lines. At
//! anything else (a quote, a lone `\r`, a ragged row, a cell that is not a finite number, a
//! number `fast-float2` does not take) it gives up with [`Bail`], and the caller reads the whole
//! file again through the reference path, which yields the same table or the positioned error.
//! So an accepted file gives the reference path's values bit for bit, and a bad one its message.

use std::io::Read;

use memchr::{memchr, memchr2, memchr_iter};

/// The fast path cannot read these lines exactly like the reference path: use that instead.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Bail;

/// What one field of a row is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Field {
    /// Not read (but counted: every row must have every field).
    Skip,
    /// A selected column: a finite number, pushed onto `columns[i]`.
    Value(usize),
    /// The time column kept verbatim.
    Time,
}

/// Parsed rows: one vector per selected column, and the time cells when asked for.
#[derive(Debug, Default)]
pub(crate) struct Rows {
    /// One vector per selected column.
    pub columns: Vec<Vec<f64>>,
    /// The time column's cells, verbatim (trimmed), when a field is [`Field::Time`].
    pub time: Vec<String>,
}

impl Rows {
    /// Empty rows for `n` selected columns.
    pub fn new(n: usize) -> Self {
        Rows {
            columns: vec![Vec::new(); n],
            time: Vec::new(),
        }
    }

    /// Rows parsed so far.
    pub fn len(&self) -> usize {
        self.columns.first().map_or(self.time.len(), Vec::len)
    }

    /// Append `other`'s rows after these.
    pub fn append(&mut self, mut other: Rows) {
        for (a, b) in self.columns.iter_mut().zip(&mut other.columns) {
            a.append(b);
        }
        self.time.append(&mut other.time);
    }
}

/// A finite number exactly as `str::parse::<f64>` reads the cell after trimming ASCII spaces and
/// tabs, or `None` when `fast-float2` does not take it (then the reference path decides).
pub(crate) fn fast_number(cell: &[u8]) -> Option<f64> {
    let start = skip_blanks(cell, 0);
    let (v, end) = number_at(cell, start)?;
    (skip_blanks(cell, end) == cell.len()).then_some(v)
}

/// The finite number starting at `at` and where it ends: the longest prefix `fast-float2` reads.
/// The caller checks that only blanks and a delimiter follow, so that the cell is exactly that
/// prefix (what `fast_number` checks, and the tests compare with `str::parse`).
#[inline]
fn number_at(bytes: &[u8], at: usize) -> Option<(f64, usize)> {
    match fast_float2::parse_partial::<f64, _>(&bytes[at..]) {
        // fast-float2 also reads "inf" and "nan"; the reference path rejects them with a message.
        Ok((v, n)) if n > 0 && v.is_finite() => Some((v, at + n)),
        _ => None,
    }
}

#[inline]
fn skip_blanks(bytes: &[u8], mut at: usize) -> usize {
    while let Some(b' ' | b'\t') = bytes.get(at) {
        at += 1;
    }
    at
}

/// Whether `bytes` may be read line by line: no quote (csv quoting may join lines) and every
/// `\r` part of a `\r\n` (the csv crate also ends a record at a lone `\r`).
fn plain_lines(bytes: &[u8]) -> bool {
    match memchr2(b'"', b'\r', bytes) {
        None => true,
        Some(_) if memchr(b'"', bytes).is_some() => false,
        Some(_) => memchr_iter(b'\r', bytes).all(|i| bytes.get(i + 1) == Some(&b'\n')),
    }
}

/// Parse every line of `bytes` (its last line may lack its `\n`) into `out`.
///
/// One pass over the bytes: a number is read where it stands (no search for its delimiter
/// first), then only blanks and the delimiter may follow.
pub(crate) fn parse_lines(bytes: &[u8], fields: &[Field], out: &mut Rows) -> Result<(), Bail> {
    if fields.is_empty() || !plain_lines(bytes) {
        return Err(Bail);
    }
    let last = fields.len() - 1;
    let len = bytes.len();
    let mut p = 0;
    while p < len {
        match bytes[p] {
            // Blank lines and comment lines are no records to the csv crate.
            b'\n' => {
                p += 1;
                continue;
            }
            b'\r' => {
                p += 2; // plain_lines: a \r is always followed by \n
                continue;
            }
            b'#' => {
                // A comment without its line end (the file's last line) is a record to the csv
                // crate: leave such a file to the reference path, so both read it alike
                // (found by fuzz/run.sh csv; fuzz/regressions/csv).
                p = p + memchr(b'\n', &bytes[p..]).ok_or(Bail)? + 1;
                continue;
            }
            _ => {}
        }
        for (i, field) in fields.iter().enumerate() {
            match *field {
                Field::Value(k) => {
                    let (v, end) = number_at(bytes, skip_blanks(bytes, p)).ok_or(Bail)?;
                    out.columns[k].push(v);
                    p = skip_blanks(bytes, end);
                }
                Field::Skip | Field::Time => {
                    let start = p;
                    while p < len && !matches!(bytes[p], b',' | b'\n' | b'\r') {
                        p += 1;
                    }
                    if *field == Field::Time {
                        // As the reference path: the csv crate's ASCII trim, then lossy UTF-8.
                        let cell = bytes[start..p].trim_ascii();
                        out.time.push(String::from_utf8_lossy(cell).into_owned());
                    }
                }
            }
            // The delimiter: a comma between fields, a line end (or the end) after the last.
            if i < last {
                if bytes.get(p) != Some(&b',') {
                    return Err(Bail); // too few fields, or not a number
                }
                p += 1;
            } else {
                match bytes.get(p) {
                    None => {}
                    Some(b'\n') => p += 1,
                    Some(b'\r') => p += 2,
                    Some(_) => return Err(Bail), // too many fields, or not a number
                }
            }
        }
    }
    Ok(())
}

/// Bytes from `from` up to just after the next `\n` (or the end).
fn line_end_after(bytes: &[u8], from: usize) -> usize {
    if from >= bytes.len() {
        return bytes.len();
    }
    memchr(b'\n', &bytes[from..]).map_or(bytes.len(), |i| from + i + 1)
}

/// Parse the lines of `data` (a mapped file from its first data line) on `threads` threads,
/// each its share in blocks of `block` bytes, calling `progress` with the bytes done.
pub(crate) fn parse_parallel(
    data: &[u8],
    fields: &[Field],
    selected: usize,
    threads: usize,
    block: usize,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Rows, Bail> {
    let threads = threads.clamp(1, 64);
    // Chunk bounds at line ends, so that every chunk holds whole lines.
    let mut bounds = vec![0];
    for k in 1..threads {
        let b = line_end_after(data, data.len() * k / threads);
        if b > *bounds.last().unwrap_or(&0) && b < data.len() {
            bounds.push(b);
        }
    }
    bounds.push(data.len());
    let parse_chunk = |chunk: &[u8]| -> Result<Rows, Bail> {
        let mut rows = Rows::new(selected);
        let mut at = 0;
        while at < chunk.len() {
            let end = line_end_after(chunk, (at + block).min(chunk.len()));
            parse_lines(&chunk[at..end], fields, &mut rows)?;
            progress((end - at) as u64);
            at = end;
        }
        Ok(rows)
    };
    let parts: Vec<Result<Rows, Bail>> = if bounds.len() == 2 {
        vec![parse_chunk(data)]
    } else {
        std::thread::scope(|s| {
            let handles: Vec<_> = bounds
                .windows(2)
                .skip(1)
                .map(|w| {
                    let chunk = &data[w[0]..w[1]];
                    s.spawn(move || parse_chunk(chunk))
                })
                .collect();
            // The first chunk on this thread while the others run.
            let mut parts = vec![parse_chunk(&data[..bounds[1]])];
            parts.extend(handles.into_iter().map(|h| h.join().unwrap_or(Err(Bail))));
            parts
        })
    };
    let mut parts = parts.into_iter();
    let mut rows = parts.next().unwrap_or(Ok(Rows::new(selected)))?;
    // Reserve once, then copy each chunk's rows behind the first's.
    let rest: Vec<Rows> = parts.collect::<Result<_, _>>()?;
    let more: usize = rest.iter().map(Rows::len).sum();
    for c in &mut rows.columns {
        c.reserve_exact(more);
    }
    for r in rest {
        rows.append(r);
    }
    Ok(rows)
}

/// A stream read in blocks by a reader thread, for gzip and other unmapped input.
pub(crate) struct Blocks {
    rx: crossbeam_channel::Receiver<std::io::Result<Vec<u8>>>,
    back: crossbeam_channel::Sender<Vec<u8>>,
}

/// Bytes a reader thread reads at a time.
pub(crate) const BLOCK: usize = 1 << 20;

impl Blocks {
    /// Start a thread reading `source` (in `scope`) in blocks of [`BLOCK`] bytes, a few ahead.
    pub fn spawn<'scope, 'env, R: Read + Send + 'scope>(
        scope: &'scope std::thread::Scope<'scope, 'env>,
        mut source: R,
    ) -> Blocks {
        let (tx, rx) = crossbeam_channel::bounded(4);
        let (back, spare) = crossbeam_channel::bounded::<Vec<u8>>(8);
        scope.spawn(move || loop {
            let mut buf = spare.try_recv().unwrap_or_default();
            buf.resize(BLOCK, 0);
            let mut n = 0;
            while n < BLOCK {
                match source.read(&mut buf[n..]) {
                    Ok(0) => break,
                    Ok(k) => n += k,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(e) => {
                        let _ = tx.send(Err(e));
                        return;
                    }
                }
            }
            buf.truncate(n);
            // The reader stops when the parser has gone (dropped its receiver).
            if n == 0 || tx.send(Ok(buf)).is_err() {
                return;
            }
        });
        Blocks { rx, back }
    }

    /// The next block; `None` at the end.
    pub fn next_block(&self) -> Option<std::io::Result<Vec<u8>>> {
        self.rx.recv().ok()
    }

    /// Give a block's buffer back for reuse.
    pub fn recycle(&self, buf: Vec<u8>) {
        let _ = self.back.try_send(buf);
    }
}

/// Reads [`Blocks`] and keeps every byte it read, so that the fast path can resume where the
/// csv crate stopped reading the header.
pub(crate) struct Recording<'a> {
    blocks: &'a Blocks,
    /// Every byte read so far.
    pub seen: Vec<u8>,
    at: usize,
    /// A read error, kept for the caller (the csv crate would only say "I/O error").
    pub error: Option<std::io::Error>,
}

impl<'a> Recording<'a> {
    /// A recording reader over `blocks`.
    pub fn new(blocks: &'a Blocks) -> Self {
        Recording {
            blocks,
            seen: Vec::new(),
            at: 0,
            error: None,
        }
    }
}

impl Read for Recording<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.at == self.seen.len() {
            match self.blocks.next_block() {
                None => return Ok(0),
                Some(Ok(b)) => {
                    self.seen.extend_from_slice(&b);
                    self.blocks.recycle(b);
                }
                Some(Err(e)) => {
                    let copy = std::io::Error::new(e.kind(), e.to_string());
                    self.error = Some(e);
                    return Err(copy);
                }
            }
        }
        let n = buf.len().min(self.seen.len() - self.at);
        buf[..n].copy_from_slice(&self.seen[self.at..self.at + n]);
        self.at += n;
        Ok(n)
    }
}

/// Parse `first` (bytes already read, from the first data line) and then every block still to
/// come: whole lines on this thread while the reader thread reads on. An I/O error is returned
/// as `Ok(Err(e))`.
pub(crate) fn parse_stream(
    first: &[u8],
    blocks: &Blocks,
    fields: &[Field],
    selected: usize,
) -> Result<std::io::Result<Rows>, Bail> {
    let mut rows = Rows::new(selected);
    // The unfinished last line of what was parsed so far.
    let mut carry: Vec<u8> = Vec::new();
    let mut feed = |bytes: &[u8], rows: &mut Rows| -> Result<(), Bail> {
        let Some(last_nl) = memchr::memrchr(b'\n', bytes) else {
            carry.extend_from_slice(bytes);
            return Ok(());
        };
        let mut body = &bytes[..=last_nl];
        if !carry.is_empty() {
            // Finish the carried line with this block's first line.
            let first_nl = memchr(b'\n', body).unwrap_or(body.len() - 1);
            carry.extend_from_slice(&body[..=first_nl]);
            parse_lines(&carry, fields, rows)?;
            carry.clear();
            body = &body[first_nl + 1..];
        }
        parse_lines(body, fields, rows)?;
        carry.extend_from_slice(&bytes[last_nl + 1..]);
        Ok(())
    };
    feed(first, &mut rows)?;
    while let Some(block) = blocks.next_block() {
        match block {
            Ok(b) => {
                feed(&b, &mut rows)?;
                blocks.recycle(b);
            }
            Err(e) => return Ok(Err(e)),
        }
    }
    parse_lines(&carry, fields, &mut rows)?;
    Ok(Ok(rows))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn reference(cell: &[u8]) -> Option<f64> {
        let v = std::str::from_utf8(cell).ok()?.trim().parse::<f64>().ok()?;
        v.is_finite().then_some(v)
    }

    /// The fast path never takes a cell the reference path reads differently.
    fn agrees(cell: &[u8]) -> Result<(), String> {
        if let Some(v) = fast_number(cell) {
            match reference(cell) {
                Some(r) if r.to_bits() == v.to_bits() => {}
                other => {
                    return Err(format!(
                        "{:?}: fast {v:e}, std {other:?}",
                        String::from_utf8_lossy(cell)
                    ))
                }
            }
        }
        Ok(())
    }

    #[test]
    fn tricky_numbers_parse_bit_for_bit_as_std() {
        let cells = [
            "0",
            "-0",
            "+0",
            "0.0",
            "-0.0",
            "1",
            "+1",
            "-1",
            "1.",
            ".5",
            "-.5",
            "+.5",
            "1e5",
            "1E5",
            "1e+5",
            "1e-5",
            "1.e5",
            "1.5e-3",
            " 1.5 ",
            "\t2\t",
            "007",
            "0.1",
            "0.2",
            "0.30000000000000004",
            "2.2250738585072014e-308",
            "2.2250738585072011e-308",
            "4.9e-324",
            "5e-324",
            "2.4703282292062327e-324",
            "2.4703282292062328e-324",
            "1.7976931348623157e308",
            "1.7976931348623158e308",
            "1.7976931348623159e308",
            "9007199254740993",
            "9007199254740992.5",
            "123456789012345678901234567890",
            "0.000000000000000000000000000000000000000001",
            "1e-400",
            "1e400",
            "-1e400",
            "2.0000000000000004440892098500626161694526672363281250000000000000001",
            "2.00000000000000044408920985006261616945266723632812",
            "4503599627370496.5",
            "4503599627370497.5",
            "1e23",
            "8.589973e9",
            "7.2057594037927933e16",
            "1448997445238699",
            "00000000000000000000001.5",
            "1.000000000000000000000000000000000000000000000000000000000000001",
            "inf",
            "-inf",
            "infinity",
            "NaN",
            "nan",
            "-nan",
            "",
            " ",
            ".",
            "-",
            "+",
            "e5",
            "1e",
            "1e+",
            "--1",
            "+-1",
            "1.5.5",
            "1e5e5",
            "0x10",
            "1_000",
            "1,5",
            "١",
            "1\u{a0}",
            "\u{a0}1",
            "1\x0b",
            "\x0c1",
            "1 2",
            "+ 1",
            "1f",
            "1d",
        ];
        for c in cells {
            agrees(c.as_bytes()).unwrap();
        }
        // And the ordinary ones are taken by the fast path, not only left to the reference.
        for c in ["1.5", "-2e-3", " 0.25", "123456.789e-2", "1.", ".5", "+3"] {
            assert!(fast_number(c.as_bytes()).is_some(), "{c}");
        }
        for c in ["inf", "NaN", "1e400", "", "1 2", "1,5", "0x10"] {
            assert_eq!(fast_number(c.as_bytes()), None, "{c}");
        }
    }

    #[test]
    fn every_short_string_of_number_characters_agrees_with_std() {
        // All strings up to length 6 over the characters numbers are made of.
        const ALPHABET: &[u8] = b"019+-.eE ";
        let mut buf = Vec::new();
        fn walk(buf: &mut Vec<u8>, depth: usize) {
            agrees(buf).unwrap();
            if depth == 0 {
                return;
            }
            for &c in ALPHABET {
                buf.push(c);
                walk(buf, depth - 1);
                buf.pop();
            }
        }
        walk(&mut buf, 6);
    }

    proptest! {
        #[test]
        fn shortest_text_of_any_float_parses_back_exactly(bits in any::<u64>()) {
            let v = f64::from_bits(bits);
            for text in [format!("{v}"), format!("{v:e}"), format!("{v:.17e}"), format!("{v:.3}")] {
                agrees(text.as_bytes()).map_err(TestCaseError::fail)?;
                if v.is_finite() && text == format!("{v}") {
                    prop_assert_eq!(fast_number(text.as_bytes()).map(f64::to_bits), Some(bits));
                }
            }
        }

        #[test]
        fn long_digit_strings_agree_with_std(
            sign in "[+-]?",
            int in "[0-9]{0,30}",
            frac in "[0-9]{0,40}",
            exp in proptest::option::of(-350i32..350),
        ) {
            let mut s = format!("{sign}{int}.{frac}");
            if let Some(e) = exp {
                s.push_str(&format!("e{e}"));
            }
            agrees(s.as_bytes()).map_err(TestCaseError::fail)?;
        }

        #[test]
        fn arbitrary_bytes_agree_with_std(cell in proptest::collection::vec(any::<u8>(), 0..24)) {
            agrees(&cell).map_err(TestCaseError::fail)?;
        }
    }

    fn parse(text: &str, fields: &[Field], n: usize) -> Result<Rows, Bail> {
        let mut rows = Rows::new(n);
        parse_lines(text.as_bytes(), fields, &mut rows).map(|()| rows)
    }

    #[test]
    fn lines_fields_comments_and_line_ends() {
        use Field::*;
        let f = [Time, Skip, Value(0), Value(1)];
        let r = parse("0.0,a,1,2\n# note\n\n1.0 , b , 3 ,\t4\r\n2.0,c,5,6", &f, 2).unwrap();
        assert_eq!(r.columns, vec![vec![1.0, 3.0, 5.0], vec![2.0, 4.0, 6.0]]);
        assert_eq!(r.time, ["0.0", "1.0", "2.0"]);
        for bad in [
            "1,a,2\n",            // too few fields
            "1,a,2,3,4\n",        // too many
            "1,a,2,x\n",          // not a number
            "1,a,2,NaN\n",        // not finite
            "1,\"a\",2,3\n",      // quoting
            "1,a,2,3\r4,b,5,6\n", // a lone \r ends a record for the csv crate
        ] {
            assert_eq!(parse(bad, &f, 2).map(|_| ()), Err(Bail), "{bad:?}");
        }
        let last_skip = [Value(0), Skip];
        assert_eq!(parse("1,a,b\n", &last_skip, 1).map(|_| ()), Err(Bail));
    }

    #[test]
    fn parallel_chunks_and_streamed_blocks_give_the_same_rows() {
        use Field::*;
        let mut text = String::from("# a comment first\n");
        for i in 0..5000 {
            text.push_str(&format!("{},{}\n", i as f64 * 0.001, -(i as f64) / 7.0));
        }
        text.push_str("1,2"); // no final newline
        let f = [Value(0), Value(1)];
        let one = parse(&text, &f, 2).unwrap();
        assert_eq!(one.len(), 5001);
        for threads in [1, 2, 3, 7] {
            for block in [1, 10, 4096, 1 << 20] {
                let r = parse_parallel(text.as_bytes(), &f, 2, threads, block, &|_| {}).unwrap();
                assert_eq!(
                    r.columns, one.columns,
                    "{threads} threads, {block} B blocks"
                );
            }
        }
        for split in [0, 1, 17, 4000, text.len()] {
            let (head, tail) = text.as_bytes().split_at(split);
            let r = std::thread::scope(|s| {
                let blocks = Blocks::spawn(s, tail);
                parse_stream(head, &blocks, &f, 2).unwrap().unwrap()
            });
            assert_eq!(r.columns, one.columns, "split at {split}");
        }
    }
}
