//! Numbers as a program writes them: read from bytes with their style, written back in it.
//!
//! A compensated program must differ from its input only where a target's value changed
//! (crate docs, rule 1), so a number is rewritten only when its new value differs from the
//! written one by more than the text can hold, and then in the file's own style: the same
//! sign, decimal point and exponent conventions, the same number of decimals when they hold
//! the value to the required resolution, more when they do not (trailing zeros beyond the
//! original count are dropped).

use std::ops::Range;

/// How a number is written, beyond its value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NumberStyle {
    /// Digits after the decimal point (of the mantissa, with an exponent).
    pub decimals: u16,
    /// Whether a decimal point is written (`1500.` has one and no decimals).
    pub point: bool,
    /// Whether a positive number carries a `+`.
    pub plus: bool,
    /// Whether a number below 1 in magnitude is written without its leading zero (`.5`).
    pub bare_point: bool,
    /// The exponent, when the number has one.
    pub exponent: Option<ExponentStyle>,
    /// Whether the decimal mark is a comma (a CSV file's `1500,25`).
    pub decimal_comma: bool,
}

/// How an exponent is written: `e5`, `E+05`, `E-005`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExponentStyle {
    /// `e` or `E`.
    pub marker: u8,
    /// Whether a non-negative exponent carries a `+`.
    pub plus: bool,
    /// The least number of exponent digits (zero-padded).
    pub digits: u16,
}

/// A number found in a file: where it is, its value and its style.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Number {
    /// Its bytes in the file.
    pub span: (usize, usize),
    /// Its value.
    pub value: f64,
    /// How it is written.
    pub style: NumberStyle,
}

impl Number {
    /// Its bytes' range in the file.
    pub fn range(&self) -> Range<usize> {
        self.span.0..self.span.1
    }
}

/// Reads a decimal number at `bytes[start..]`: an optional sign, digits with an optional
/// decimal point (at least one digit), an optional exponent. `None` when there is none
/// there or its value is not finite (a 400-digit literal).
pub fn parse_number(bytes: &[u8], start: usize) -> Option<Number> {
    let mut i = start;
    let at = |i: usize| bytes.get(i).copied();
    let mut plus = false;
    match at(i) {
        Some(b'+') => {
            plus = true;
            i += 1;
        }
        Some(b'-') => i += 1,
        _ => {}
    }
    let integer_start = i;
    while at(i).is_some_and(|b| b.is_ascii_digit()) {
        i += 1;
    }
    let integer_digits = i - integer_start;
    let mut point = false;
    let mut decimals = 0;
    if at(i) == Some(b'.') {
        let mut j = i + 1;
        while at(j).is_some_and(|b| b.is_ascii_digit()) {
            j += 1;
        }
        if integer_digits > 0 || j > i + 1 {
            point = true;
            decimals = j - i - 1;
            i = j;
        }
    }
    if integer_digits == 0 && decimals == 0 {
        return None;
    }
    let mut exponent = None;
    if let Some(marker @ (b'e' | b'E')) = at(i) {
        let mut j = i + 1;
        let mut exp_plus = false;
        match at(j) {
            Some(b'+') => {
                exp_plus = true;
                j += 1;
            }
            Some(b'-') => j += 1,
            _ => {}
        }
        let digits_start = j;
        while at(j).is_some_and(|b| b.is_ascii_digit()) {
            j += 1;
        }
        if j > digits_start {
            exponent = Some(ExponentStyle {
                marker,
                plus: exp_plus,
                digits: saturating_u16(j - digits_start),
            });
            i = j;
        }
    }
    let text = std::str::from_utf8(&bytes[start..i]).ok()?;
    let value: f64 = text.parse().ok()?;
    if !value.is_finite() {
        return None;
    }
    Some(Number {
        span: (start, i),
        value,
        style: NumberStyle {
            decimals: saturating_u16(decimals),
            point,
            plus,
            bare_point: integer_digits == 0,
            exponent,
            decimal_comma: false,
        },
    })
}

/// A count of digits as a style keeps it: beyond 65,535 (a line's worth) an `f64` has long
/// run out of digits, and the count only pads a number nobody writes.
fn saturating_u16(count: usize) -> u16 {
    u16::try_from(count).unwrap_or(u16::MAX)
}

/// The most decimals ever written: beyond it an `f64` has no digits left.
const MAX_DECIMALS: usize = 17;

/// `value` written in `style` with at least `required_decimals` decimals (of the plain
/// number: an exponent's mantissa gets as many more as the exponent takes away), trailing
/// zeros beyond the style's own count dropped. A value that rounds to zero is written
/// without a minus sign unless it is a negative zero.
pub fn format_number(value: f64, style: &NumberStyle, required_decimals: usize) -> String {
    let mut text = match style.exponent {
        None => {
            let decimals = usize::from(style.decimals)
                .max(required_decimals)
                .min(MAX_DECIMALS);
            let mut text = format!("{value:.decimals$}");
            trim_zeros(&mut text, usize::from(style.decimals), style.point);
            text
        }
        Some(exp) => {
            let magnitude = if value == 0.0 {
                0
            } else {
                value.abs().log10().floor() as i64
            };
            let needed = (required_decimals as i64 + magnitude).max(0) as usize;
            let decimals = usize::from(style.decimals).max(needed).min(MAX_DECIMALS);
            let rust = format!("{value:.decimals$e}");
            let (mantissa, exponent) = rust.split_once('e').unwrap_or((&rust, "0"));
            let mut mantissa = mantissa.to_string();
            trim_zeros(&mut mantissa, usize::from(style.decimals), style.point);
            let exponent: i64 = exponent.parse().unwrap_or(0);
            let sign = if exponent < 0 {
                "-"
            } else if exp.plus {
                "+"
            } else {
                ""
            };
            format!(
                "{mantissa}{}{sign}{:0width$}",
                exp.marker as char,
                exponent.abs(),
                width = usize::from(exp.digits)
            )
        }
    };
    let digits_all_zero = !text
        .bytes()
        .take_while(|b| !matches!(b, b'e' | b'E'))
        .any(|b| (b'1'..=b'9').contains(&b));
    if digits_all_zero && text.starts_with('-') && !(value == 0.0 && value.is_sign_negative()) {
        text.remove(0);
    }
    if style.bare_point {
        if let Some(rest) = text.strip_prefix("0.") {
            text = format!(".{rest}");
        } else if let Some(rest) = text.strip_prefix("-0.") {
            text = format!("-.{rest}");
        }
    }
    if style.plus && !text.starts_with('-') {
        text.insert(0, '+');
    }
    if style.decimal_comma {
        text = text.replace('.', ",");
    }
    text
}

/// Drops trailing zeros after the point down to `keep` decimals, and the point itself when
/// none remain and the style writes none.
fn trim_zeros(text: &mut String, keep: usize, point: bool) {
    let Some(dot) = text.find('.') else {
        return;
    };
    while text.len() > dot + 1 + keep && text.ends_with('0') {
        text.pop();
    }
    if text.len() == dot + 1 && !point {
        text.pop();
    }
}

/// The text to replace `number` with for `new_value`, or `None` when the written text
/// already holds `new_value` — to within half a unit of its own last decimal and of
/// `required_decimals` — so that a target that does not change keeps its bytes.
pub fn rewrite(
    number: &Number,
    original: &[u8],
    new_value: f64,
    required_decimals: usize,
) -> Option<String> {
    let exponent = number.style.exponent.map_or(0, |_| {
        if number.value == 0.0 {
            0
        } else {
            number.value.abs().log10().floor() as i32
        }
    });
    let own_unit = 10f64.powi(exponent - i32::from(number.style.decimals));
    let required_unit = 10f64.powi(-(required_decimals as i32));
    let half_unit = 0.5 * own_unit.min(required_unit);
    if (new_value - number.value).abs() <= half_unit {
        return None;
    }
    let text = format_number(new_value, &number.style, required_decimals);
    (text.as_bytes() != original).then_some(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parsed(text: &str) -> Number {
        let n = parse_number(text.as_bytes(), 0).unwrap();
        assert_eq!(n.span, (0, text.len()), "{text}");
        n
    }

    #[test]
    fn styles_are_read_as_written() {
        let n = parsed("1500.25");
        assert_eq!(
            (n.value, n.style.decimals, n.style.point),
            (1500.25, 2, true)
        );
        let n = parsed("-90");
        assert_eq!(
            (n.value, n.style.decimals, n.style.point),
            (-90.0, 0, false)
        );
        let n = parsed("+.5");
        assert!(n.style.plus && n.style.bare_point);
        let n = parsed("1.5E+03");
        assert_eq!(n.value, 1500.0);
        let e = n.style.exponent.unwrap();
        assert_eq!((e.marker, e.plus, e.digits), (b'E', true, 2));
        let n = parsed("1500.");
        assert_eq!((n.style.decimals, n.style.point), (0, true));
        assert!(parse_number(b"-", 0).is_none());
        assert!(parse_number(b".", 0).is_none());
        assert!(parse_number(b"x1", 0).is_none());
        // An exponent without digits is not part of the number.
        assert_eq!(parse_number(b"2e", 0).unwrap().span, (0, 1));
        assert!(parse_number(format!("1{}", "0".repeat(400)).as_bytes(), 0).is_none());
    }

    #[test]
    fn formatting_keeps_the_style_and_adds_decimals_only_when_needed() {
        let style = parsed("1500.0").style;
        assert_eq!(format_number(1501.25, &style, 4), "1501.25");
        assert_eq!(format_number(1501.123456, &style, 4), "1501.1235");
        assert_eq!(format_number(1501.0, &style, 4), "1501.0");
        let style = parsed("90").style;
        assert_eq!(format_number(89.9999995, &style, 6), "90");
        assert_eq!(format_number(89.99, &style, 6), "89.99");
        assert_eq!(format_number(-1e-9, &style, 6), "0");
        assert_eq!(format_number(-1e-9, &parsed("0.0").style, 6), "0.0");
        assert_eq!(format_number(0.25, &parsed(".5").style, 4), ".25");
        assert_eq!(format_number(-0.25, &parsed(".5").style, 4), "-.25");
        assert_eq!(format_number(3.0, &parsed("+1.00").style, 4), "+3.00");
        assert_eq!(
            format_number(1501.5, &parsed("1.5E+03").style, 4),
            "1.5015E+03"
        );
        assert_eq!(
            format_number(0.00125, &parsed("1.0e-3").style, 7),
            "1.25e-3"
        );
        assert_eq!(format_number(2.0, &parsed("1500.").style, 4), "2.");
    }

    #[test]
    fn a_value_the_text_already_holds_is_not_rewritten() {
        let text = "1500.0";
        let n = parsed(text);
        assert_eq!(rewrite(&n, text.as_bytes(), 1500.0 + 1e-12, 4), None);
        assert_eq!(rewrite(&n, text.as_bytes(), 1500.00004, 4), None);
        assert_eq!(
            rewrite(&n, text.as_bytes(), 1500.0002, 4).as_deref(),
            Some("1500.0002")
        );
        let text = "-0.0";
        let n = parsed(text);
        assert_eq!(rewrite(&n, text.as_bytes(), 1e-13, 4), None);
    }

    use proptest::prelude::*;

    fn style_strategy() -> impl Strategy<Value = NumberStyle> {
        (
            0..9u16,
            any::<bool>(),
            any::<bool>(),
            any::<bool>(),
            prop::option::of((any::<bool>(), any::<bool>(), 1..4u16)),
        )
            .prop_map(
                |(decimals, point, plus, bare_point, exponent)| NumberStyle {
                    decimals,
                    point: point || decimals > 0,
                    plus,
                    bare_point: bare_point && decimals > 0,
                    exponent: exponent.map(|(upper, plus, digits)| ExponentStyle {
                        marker: if upper { b'E' } else { b'e' },
                        plus,
                        digits,
                    }),
                    decimal_comma: false,
                },
            )
    }

    proptest! {
        /// A number written in any style reads back within half a unit of its last decimal
        /// (and of the decimals required), and keeps the style's marks.
        #[test]
        fn formatted_numbers_read_back_within_their_resolution(
            value in prop_oneof![-5000.0..5000.0f64, -1.0..1.0f64, Just(0.0)],
            style in style_strategy(),
            required in 0..9usize,
        ) {
            let text = format_number(value, &style, required);
            let back = parse_number(text.as_bytes(), 0).unwrap();
            prop_assert_eq!(back.span, (0, text.len()), "{}", text);
            let exponent = style.exponent.map_or(0, |_| if value == 0.0 { 0 } else { value.abs().log10().floor() as i32 });
            let resolution = 0.5 * 10f64.powi(-(required as i32)).max(10f64.powi(exponent - 17));
            prop_assert!((back.value - value).abs() <= resolution * (1.0 + 1e-9) + 1e-12 * value.abs(), "{} for {}", text, value);
            prop_assert_eq!(back.style.exponent.map(|e| e.marker), style.exponent.map(|e| e.marker));
            prop_assert!(back.style.decimals >= style.decimals, "{} in {:?}", text, style);
            if style.plus && !text.starts_with('-') {
                prop_assert!(text.starts_with('+'));
            }
        }

        /// Parse then format gives the text back; and a value the text holds is never
        /// rewritten.
        #[test]
        fn parse_then_format_round_trips(value in -5000.0..5000.0f64, style in style_strategy(), required in 0..9usize) {
            let text = format_number(value, &style, 0);
            let n = parse_number(text.as_bytes(), 0).unwrap();
            prop_assert_eq!(format_number(n.value, &n.style, 0), text.clone());
            prop_assert_eq!(rewrite(&n, text.as_bytes(), n.value, required), None);
        }
    }
}
