"""One number format for every page's tables and figures: engineering notation (the exponent a multiple of 3,
read as a unit's prefix: 145, 6.26e-6 for 6.26 micro, 1.45e3), the same digits in a table's cell and on the bar
that draws it."""
from __future__ import annotations

import html
import math
import re

DIGITS = 3  # significant digits of a value; its std or bound with 2


def eng(value: float | None, digits: int = DIGITS, unit: str = "") -> str:
    """`value` with `digits` significant digits in engineering notation, then the unit; "-" for None."""
    if value is None:
        return "-"
    v = float(value)
    if v == 0 or not math.isfinite(v):
        text = "0" if v == 0 else str(v)
    else:
        v = float(f"{v:.{digits}g}")  # rounded first: 999.7 is 1e3, not 1000
        power = 3 * math.floor(math.log10(abs(v)) / 3)
        mantissa = v / 10.0 ** power  # 1 to 999: its integer digits all shown, even where more than `digits`
        text = f"{mantissa:.{max(digits, len(str(int(abs(mantissa)))))}g}" + (f"e{power}" if power else "")
    return f"{text} {unit}" if unit else text


class Html(str):
    """Text that is HTML already (a table's cell takes it as it is)."""


def value_digits(value: float, u: float) -> int:
    """The significant digits of a value stated with its uncertainty: down to u's second digit (at least 3)."""
    if not (math.isfinite(value) and math.isfinite(u)) or value == 0 or u <= 0:
        return 3
    return max(3, math.floor(math.log10(abs(value))) - math.floor(math.log10(u)) + 2)


def eng_html(value: float | None, digits: int = DIGITS, unit: str = "") -> Html:
    """eng() for a page: one unbreakable span, so that a narrow cell never wraps a number at its exponent."""
    return Html(f"<span class='n'>{html.escape(eng(value, digits, unit))}</span>")


def words_html(text: str) -> Html:
    """Text for a page, each number in it unbreakable (a narrow cell wraps the words, never a number)."""
    def unbreakable(number: re.Match[str]) -> str:
        return f"<span class='n'>{number.group(0)}</span>"
    return Html(re.sub(r"[-+]?\d[\d.]*(?:e[-+]?\d+)?", unbreakable,
                       html.escape(text, quote=False)))  # quote=False: no &#x27; whose digits it would wrap


def cell_html(value, digits: int = DIGITS) -> str:
    """A table's cell: a float as eng_html, an int as it is, a bool as "yes" or nothing, None as nothing, Html as
    it is, other text escaped."""
    if isinstance(value, Html):
        return value
    if value is None or value is False:
        return ""
    if value is True:
        return "yes"
    if isinstance(value, float):
        return eng_html(value, digits)
    return html.escape(str(value))
