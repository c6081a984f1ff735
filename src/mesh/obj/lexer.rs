//! The tokens of one OBJ line and the numbers in them, read as they are scanned: eight bytes at
//! a time where the line allows, plain decimals and short indices on the spot, anything else by
//! the standard parser, so every number is bit for bit what `str::parse` gives. Not here: what
//! the tokens mean (`parser.rs`).

/// The tokens of one line, read from the left. The line is `text[..end]` from where reading
/// started; `text` goes on past it (to the end of the chunk), so eight bytes at a time can be
/// looked at near the line's end: the `\n` at `end` is neither a digit nor part of a token, so
/// no run found that way goes past the line.
pub(super) struct Line<'a> {
    pub(super) text: &'a [u8],
    pub(super) end: usize,
    /// Where the next token is looked for.
    pub(super) at: usize,
}

const ONES: u64 = 0x0101_0101_0101_0101;
const HIGHS: u64 = ONES * 0x80;

/// The eight bytes of `t` from `i` as a little-endian word (the first byte lowest), if there
/// are eight.
#[inline]
fn word(t: &[u8], i: usize) -> Option<u64> {
    let w: [u8; 8] = t.get(i..i + 8)?.try_into().ok()?;
    Some(u64::from_le_bytes(w))
}

/// How many of the bytes of `w` (from its lowest) are ASCII digits before the first that is
/// not, and `w` with every byte XORed with `b'0'` (a digit byte then holds its value).
#[inline]
fn leading_digits(w: u64) -> (usize, u64) {
    let t = w ^ (ONES * b'0' as u64); // b'0'..=b'9' become 0..=9, every other byte 10 or more
    // The high bit of a byte is set when its low seven bits are 10 or more (adding 0x76 to at
    // most 0x7f carries into no other byte), or when it was set already.
    let not_digit = (((t & !HIGHS) + ONES * 0x76) | t) & HIGHS;
    ((not_digit.trailing_zeros() / 8) as usize, t)
}

/// The number written by the first `n` (1 to 8) digit values of `t` (as [`leading_digits`]
/// gives them): the other bytes are shifted out and zeros (leading zeros of the number)
/// shifted in, then the eight digits are combined in three multiplications (as the standard
/// library's float parser does).
#[inline]
fn digits_value(t: u64, n: usize) -> u64 {
    debug_assert!((1..=8).contains(&n));
    let v = t << (8 * (8 - n));
    let v = v * 10 + (v >> 8); // pairs of digits, in every other byte
    let v1 = (v & 0x0000_00ff_0000_00ff).wrapping_mul(100 + (1_000_000 << 32));
    let v2 = ((v >> 16) & 0x0000_00ff_0000_00ff).wrapping_mul(1 + (10_000 << 32));
    (v1.wrapping_add(v2) >> 32) as u32 as u64
}

/// 10^0 to 10^19, the powers of ten that u64 holds.
const POW10_U64: [u64; 20] = {
    let mut p = [1u64; 20];
    let mut i = 1;
    while i < 20 {
        p[i] = p[i - 1] * 10;
        i += 1;
    }
    p
};

impl<'a> Line<'a> {
    /// Moves past the whitespace at `at`.
    #[inline]
    fn skip_space(&mut self) {
        while self.at < self.end && self.text[self.at].is_ascii_whitespace() {
            self.at += 1;
        }
    }

    /// The end of the token that `i` is in (or starts): the first whitespace from `i` on, or
    /// the end of the line.
    #[inline]
    fn token_end(&self, mut i: usize) -> usize {
        let t = self.text;
        while i < self.end {
            let Some(w) = word(t, i) else {
                while i < self.end && !t[i].is_ascii_whitespace() {
                    i += 1;
                }
                return i;
            };
            // The first byte below 0x21 (every whitespace is): the lowest flag of this
            // classic test is exact (a borrow only reaches the bytes above the one it came from).
            let low = w.wrapping_sub(ONES * 0x21) & !w & HIGHS;
            if low == 0 {
                i += 8;
                continue;
            }
            i += (low.trailing_zeros() / 8) as usize;
            if i >= self.end || t[i].is_ascii_whitespace() {
                return i.min(self.end);
            }
            i += 1; // a control byte that is not whitespace: part of the token
        }
        self.end
    }

    /// Whether a token that was being read ends at `i` (whitespace or the end of the line).
    #[inline]
    fn ends_token(&self, i: usize) -> bool {
        i >= self.end || self.text[i].is_ascii_whitespace()
    }

    /// The ASCII digits from `i`: how many, and the number they write (modulo 2^64 when
    /// there are more than 19).
    #[inline]
    fn digits(&self, mut i: usize) -> (usize, u64) {
        let (start, t) = (i, self.text);
        let mut m: u64 = 0;
        while let Some(w) = word(t, i) {
            let (n, d) = leading_digits(w);
            if n > 0 {
                m = m
                    .wrapping_mul(POW10_U64[n])
                    .wrapping_add(digits_value(d, n));
                i += n;
            }
            if n < 8 {
                return (i - start, m);
            }
        }
        while i < self.end && t[i].is_ascii_digit() {
            m = m.wrapping_mul(10).wrapping_add((t[i] - b'0') as u64);
            i += 1;
        }
        (i - start, m)
    }

    /// Reads the first token: `b'v'` or `b'f'` when it is that one letter, `b't'` for `vt`,
    /// `b'u'` for `usemtl`, `b'm'` for `mtllib`, else 0.
    #[inline]
    pub(super) fn keyword(&mut self) -> u8 {
        self.skip_space();
        if self.at < self.end {
            let k = self.text[self.at];
            if (k == b'v' || k == b'f') && self.ends_token(self.at + 1) {
                self.at += 1;
                return k;
            }
            for (word, code) in [
                (&b"usemtl"[..], b'u'),
                (&b"mtllib"[..], b'm'),
                (&b"vt"[..], b't'),
            ] {
                if k == word[0]
                    && self.text[self.at..self.end].starts_with(word)
                    && self.ends_token(self.at + word.len())
                {
                    self.at += word.len();
                    return code;
                }
            }
        }
        0
    }

    /// The rest of the line, without the whitespace around it (a `usemtl` line's name).
    pub(super) fn rest(&mut self) -> &'a [u8] {
        self.skip_space();
        let r = self.text[self.at..self.end].trim_ascii_end();
        self.at = self.end;
        r
    }

    /// The next token's start, whether it has a minus sign, and the run of digits after its
    /// sign (as [`Self::digits`] reads it), or `None` at the end of the line. Always inlined:
    /// left to the compiler it was not, and the parse of spot took 12 % longer.
    #[inline(always)]
    fn signed_digits(&mut self) -> Option<Signed> {
        self.skip_space();
        let (t, start) = (self.text, self.at);
        if start >= self.end {
            return None;
        }
        let neg = t[start] == b'-';
        let first = start + (neg || t[start] == b'+') as usize;
        let (count, value) = self.digits(first);
        Some(Signed {
            start,
            neg,
            end: first + count,
            count,
            value,
        })
    }

    /// The token from `start` (through `i`, where its fast reading stopped), moving past it:
    /// for the standard parsers.
    #[inline]
    fn whole_token(&mut self, start: usize, i: usize) -> &'a [u8] {
        self.at = self.token_end(i);
        &self.text[start..self.at]
    }

    /// The next token as a number (`Err`: the token, which is not one), or `None` at the end
    /// of the line, bit for bit what `str::parse::<f64>` makes of the token.
    ///
    /// A plain decimal (`[+-]digits[.digits]`, 19 digits at most, whose digits as an integer
    /// are at most 2^53 and with at most 22 after the point), what OBJ files are made of, is
    /// read as it is scanned: the digits and the power of ten are both exact in f64, so their
    /// quotient is the correctly rounded value, which is what the standard parser computes for
    /// them too (its own fast path). Any other token (exponents, more digits, `inf`, `nan`,
    /// garbage) goes to the standard parser.
    #[inline]
    pub(super) fn float(&mut self) -> Option<Result<f64, &'a [u8]>> {
        let Signed {
            start,
            neg,
            end: mut i,
            count: whole,
            value: mut m,
        } = self.signed_digits()?;
        let mut frac = 0;
        if i < self.end && self.text[i] == b'.' {
            let (n, f) = self.digits(i + 1);
            // Only used when there are 19 digits or fewer in all (so 10^n does not matter
            // otherwise).
            m = m.wrapping_mul(POW10_U64[n.min(19)]).wrapping_add(f);
            (frac, i) = (n, i + 1 + n);
        }
        let digits = whole + frac;
        // A plain decimal, as above (19 digits cannot overflow u64).
        if self.ends_token(i) && digits > 0 && digits <= 19 && m <= 1 << 53 && frac <= 22 {
            self.at = i;
            // `-v` is `v` with the sign bit set (v is not negative): set without a branch, as
            // the signs of coordinates are as good as random.
            let v = m as f64 / POW10[frac];
            return Some(Ok(f64::from_bits(v.to_bits() | (neg as u64) << 63)));
        }
        let tok = self.whole_token(start, i);
        Some(std_parse(tok).ok_or(tok))
    }

    /// The vertex index of the next token (what comes before its first `/`; `Err`: the token,
    /// whose index is not a number, as `str::parse::<i64>` reads it), or `None` at the end of
    /// the line. Up to 18 digits with an optional sign are read as they are scanned, anything
    /// else by the standard parser.
    #[inline]
    pub(super) fn index(&mut self) -> Option<Result<i64, &'a [u8]>> {
        let Signed {
            start,
            neg,
            end: i,
            count,
            value,
        } = self.signed_digits()?;
        if count > 0 && count <= 18 && (self.ends_token(i) || self.text[i] == b'/') {
            self.at = self.token_end(i);
            let n = value as i64;
            return Some(Ok(if neg { -n } else { n }));
        }
        let tok = self.whole_token(start, i);
        let idx = tok.split(|&c| c == b'/').next().unwrap_or(tok);
        Some(std_parse(idx).ok_or(tok))
    }
}

impl<'a> Line<'a> {
    /// The vertex index and texture coordinate index of the next face corner (`a`, `a/b`,
    /// `a//c`, `a/b/c`; the second `None` when not written or not a number), or `None` at the
    /// end of the line; `Err`: the token, when the vertex index is not a number as
    /// `str::parse::<i64>` reads it (as [`Line::index`] refuses it). Short
    /// indices are read as they are scanned, anything else by the standard parser.
    #[inline]
    pub(super) fn corner(&mut self) -> Option<Corner<'a>> {
        let first = self.signed_digits()?;
        let value = |d: &Signed| {
            let n = d.value as i64;
            if d.neg { -n } else { n }
        };
        let short = |d: &Signed| d.count > 0 && d.count <= 18;
        if short(&first) {
            if self.ends_token(first.end) {
                self.at = first.end;
                return Some(Ok((value(&first), None)));
            }
            if self.text[first.end] == b'/' {
                self.at = first.end + 1;
                if self.ends_token(self.at) || self.text[self.at] == b'/' {
                    self.at = self.token_end(self.at);
                    return Some(Ok((value(&first), None)));
                }
                let start = self.at;
                let neg = self.text[start] == b'-';
                let d0 = start + (neg || self.text[start] == b'+') as usize;
                let (count, v) = self.digits(d0);
                let second = Signed {
                    start,
                    neg,
                    end: d0 + count,
                    count,
                    value: v,
                };
                if short(&second) && (self.ends_token(second.end) || self.text[second.end] == b'/')
                {
                    self.at = self.token_end(second.end);
                    return Some(Ok((value(&first), Some(value(&second)))));
                }
            }
        }
        let tok = self.whole_token(first.start, first.end);
        let mut parts = tok.split(|&c| c == b'/');
        // A texture coordinate index that is not a number is taken as absent (the vertex
        // index is what a face needs; the reader without texture coordinates ignores it too).
        Some(match parts.next().and_then(std_parse) {
            Some(v) => Ok((v, parts.next().and_then(std_parse))),
            None => Err(tok),
        })
    }
}

/// A face corner's vertex and texture coordinate indices ([`Line::corner`]), or the token whose
/// vertex index is not a number.
pub(super) type Corner<'a> = Result<(i64, Option<i64>), &'a [u8]>;

/// What [`Line::signed_digits`] read of a token.
struct Signed {
    start: usize,
    neg: bool,
    /// Where the digits after the sign end.
    end: usize,
    /// How many digits, and the number they write (modulo 2^64 past 19 of them).
    count: usize,
    value: u64,
}

/// 10^0 to 10^22, the powers of ten that f64 holds exactly.
pub(super) const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// `t` read by the standard parser (`str::parse`), `None` where it refuses it: the tokens
/// that [`Line::float`] and [`Line::index`] do not read themselves.
fn std_parse<T: std::str::FromStr>(t: &[u8]) -> Option<T> {
    std::str::from_utf8(t).ok()?.parse().ok()
}
