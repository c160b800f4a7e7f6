"""The RS274/NGC language as LinuxCNC runs it: tokenizer, expressions, parameters, O-words.

This module knows nothing about motion. :class:`Program` reads a program's text and
:meth:`Program.blocks` *executes its language* — parameter assignments, expressions,
subroutine calls and control flow — and yields one :class:`Block` per executed line that
holds machine words, with every word's value evaluated. The rest of :mod:`nurbsmotion.paths.gcode`
turns the blocks into a path.

What is read (LinuxCNC 2.9 manual, chapters "G-code overview" and "O codes")
    * Lines: case-insensitive, spaces and tabs ignored outside comments; comments
      ``( ... )`` and ``; ...``; a leading ``/`` (block delete, the switch is off: the line
      runs); ``N`` line numbers; a first and a last line ``%``; CRLF, CR or LF endings and
      a UTF-8 byte-order mark.
    * Values: numbers, ``#n`` numbered parameters (``#1``.. ``#5602``), ``#<name>`` local
      named and ``#<_name>`` global named parameters (read-only system parameters such as
      ``#<_x>`` through a callback), ``#[expr]``/``##n`` indirection, ``[expr]``.
    * Operators, by binding (tightest first): ``**``; ``* / MOD``; ``+ -``;
      ``EQ NE GT GE LT LE``; ``AND OR XOR``. Unary functions ``ABS ACOS ASIN COS EXP FIX
      FUP LN ROUND SIN SQRT TAN`` (angles in degrees), ``ATAN[y]/[x]`` and
      ``EXISTS[#<name>]``.
    * ``#n = value`` assignments take effect after the line's words are read, in order.
    * O-words (numbered ``o100`` or named ``o<name>``): ``sub``/``endsub [value]``,
      ``call [arg]...`` (args become ``#1``.. ``#30``, local to the call with the named
      locals), ``return [value]`` (sets ``#<_value>`` and ``#<_value_returned>``),
      ``if``/``elseif``/``else``/``endif``, ``while``/``endwhile``, ``do``/``while``,
      ``repeat``/``endrepeat``, ``break``, ``continue``. A subroutine is defined in the
      program, or in a file ``name.ngc`` that the motion layer appends to the program's
      lines (:func:`~nurbsmotion.paths.gcode.reader.load_gcode`'s ``subroutine_path``).
    * A nested comment ``(a (b) c)``, which LinuxCNC refuses, is read as one comment; its
      lines are listed in :attr:`Program.nested_comments`. ``#<_hal[...]>`` and
      ``#<_ini[...]>`` (a running LinuxCNC's HAL pins and INI file) are refused.

Limits (documented refusals, each a :class:`~nurbsmotion.errors.PathFileError` naming the
line): a number literal of more than :data:`MAX_NUMBER_CHARS` characters; subroutine calls
nested deeper than :data:`MAX_CALL_DEPTH`; more than :data:`MAX_EXTRA_BLOCKS` executed
lines beyond 10 per line of text (an endless loop is refused instead of hanging).
"""

from __future__ import annotations

import math
import re
from bisect import bisect_left, bisect_right
from itertools import compress
from operator import itemgetter, not_
from typing import Callable, Iterator, NamedTuple

import numpy as np

from ...errors import PathFileError

__all__ = ["Block", "Rows", "WordTable", "Program", "split_lines", "MAX_NUMBER_CHARS", "MAX_CALL_DEPTH",
           "MAX_EXTRA_BLOCKS", "MAX_LINE_LENGTH"]

MAX_LINE_LENGTH = 256
"""Longest line read [characters]; LinuxCNC's own limit (LINELEN) is 255."""
MAX_NUMBER_CHARS = 40
"""Longest number literal read [characters]; a double holds 17 significant digits."""
MAX_CALL_DEPTH = 64
"""Deepest subroutine nesting (LinuxCNC allows 10 in 2.9; a recursion beyond is a loop)."""
MAX_EXTRA_BLOCKS = 1_000_000
"""Executed lines allowed beyond 10 per line of the program's text."""
_N_NUMBERED = 5603  # numbered parameters #0 .. #5602 (RS274NGC_MAX_PARAMETERS)


class Block(NamedTuple):
    """One executed line with machine words (a named tuple: cheap for programs of
    millions of lines).

    Attributes
    ----------
    line : int
        1-based line number in the file.
    g, m : tuple of float
        G and M codes in the order written.
    words : dict
        Every other word (upper-case letter -> value), ``N`` dropped.
    """

    line: int
    g: tuple
    m: tuple
    words: dict


class WordTable:
    """The words of a program's plain lines, read in bulk as columns.

    A plain line is what CAM systems write: letter-number words only (no N or O word, no
    parameter or expression), an optional block delete, N number and trailing comment.
    Each such line with at least one word is a *row*; the words of row ``r`` are
    ``offsets[r]:offsets[r + 1]``, in the order written. A line whose numbers ``float``
    refuses ("1.2.3"), with a literal of :data:`MAX_NUMBER_CHARS` characters or more, or
    with a letter other than G or M twice is not plain: the full parser reads it when it
    runs, and names its error.

    Attributes
    ----------
    line : ndarray of int64, shape (n_rows,)
        1-based line number of each row.
    offsets : ndarray of int64, shape (n_rows + 1,)
        First word of each row.
    letter : ndarray of uint8, shape (n_words,)
        Each word's letter (ASCII code, upper case).
    value : ndarray of float64, shape (n_words,)
        Each word's number.
    plain : ndarray of bool, shape (n_lines,)
        Whether each line is plain (blank and comment-only lines are, without a row).
    """

    def __init__(self, lines: list[str], start: int, stop: int):
        plain = np.zeros(len(lines), dtype=bool)
        row_lines, counts, letters, values = [], [], [], []
        for a in range(start, stop, _TABLE_CHUNK):
            b = min(stop, a + _TABLE_CHUNK)
            found = _PLAIN_LINE.findall("\n".join(lines[a:b]))
            if len(found) != b - a:  # cannot happen (one match per line); read them all in full
                continue
            is_plain = list(map(not_, map(itemgetter(1), found)))
            index = a + np.flatnonzero(is_plain)  # line index of each plain line
            joined = "\n".join(compress(map(itemgetter(0), found), is_plain))
            del found, is_plain
            text = np.frombuffer(joined.encode("ascii"), dtype=np.uint8)
            at = np.flatnonzero((text >= 65) & (text <= 90))  # each word's letter
            row = np.searchsorted(np.flatnonzero(text == 10), at)  # its plain line (0-based)
            letter = text[at]
            tokens = joined.translate(_LETTERS_TO_BLANKS).split()
            bad = np.zeros(len(index), dtype=bool)
            if tokens and max(map(len, tokens)) >= MAX_NUMBER_CHARS:
                bad[row[np.fromiter(map(len, tokens), dtype=np.int64, count=len(tokens))
                        >= MAX_NUMBER_CHARS]] = True
            try:
                value = np.array(tokens, dtype=float)
            except ValueError:
                value = np.array([_float_or_nan(t) for t in tokens])
                bad[row[np.isnan(value)]] = True
            del tokens
            single = (letter != ord("G")) & (letter != ord("M"))
            key = np.sort(row[single] * 32 + (letter[single] - 65))
            bad[key[1:][key[1:] == key[:-1]] // 32] = True
            n_words = np.bincount(row, minlength=len(index))
            plain[index[~bad]] = True
            keep = ~bad & (n_words > 0)
            row_lines.append(index[keep] + 1)
            counts.append(n_words[keep])
            kept = keep[row]
            letters.append(letter[kept])
            values.append(value[kept])
        self.plain = plain
        self.line = np.concatenate(row_lines or [np.empty(0, np.int64)]).astype(np.int64)
        self.offsets = np.concatenate([[0], np.cumsum(np.concatenate(counts or [np.empty(0, np.int64)]))]
                                      ).astype(np.int64)
        self.letter = np.concatenate(letters or [np.empty(0, np.uint8)])
        self.value = np.concatenate(values or [np.empty(0)])

    def __len__(self) -> int:
        return len(self.line)

    def block(self, r: int) -> Block:
        """Row ``r`` as a :class:`Block`."""
        a, b = int(self.offsets[r]), int(self.offsets[r + 1])
        g, m, words = [], [], {}
        for code, v in zip(self.letter[a:b].tolist(), self.value[a:b].tolist()):
            if code == 71:  # G
                g.append(v)
            elif code == 77:  # M
                m.append(v)
            else:
                words[chr(code)] = v
        return Block(int(self.line[r]), tuple(g), tuple(m), words)


class Rows(NamedTuple):
    """Rows ``start .. stop - 1`` of a :class:`WordTable`: consecutive plain lines of the
    program, executed one after the other (:meth:`Program.blocks` with ``runs=True``)."""

    table: WordTable
    start: int
    stop: int

    def each(self) -> Iterator[Block]:
        """The rows one :class:`Block` at a time."""
        return (self.table.block(r) for r in range(self.start, self.stop))


def _float_or_nan(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan


def split_lines(data: bytes, source: str, upper: bool = False) -> list[str]:
    """The lines of a program file: UTF-8 (an optional byte-order mark dropped), any of
    CRLF/CR/LF endings, each at most :data:`MAX_LINE_LENGTH` characters; upper-cased
    with ``upper`` (the form :class:`Program` reads fastest)."""
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise PathFileError("line is not UTF-8 text; is this a G-code file?", source, line) from None
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    if lines and max(map(len, lines)) > MAX_LINE_LENGTH:
        i = next(i for i, t in enumerate(lines) if len(t) > MAX_LINE_LENGTH)
        raise PathFileError(f"line is longer than {MAX_LINE_LENGTH} characters; is this a G-code "
                            "file?", source, i + 1)
    if upper:  # one call for the whole text (upper-casing never makes or removes a line break)
        lines = text.upper().split("\n")[: len(lines)]
    return lines


# ---------------------------------------------------------------------- tokenizer
# one way to match each number ("\d+\.?\d*" had many, and backtracked exponentially)
_PLAIN = re.compile(r"(?:[a-z][+-]?(?:\d+(?:\.\d*)?|\.\d+))*\Z")
_PLAIN_WORD = re.compile(r"([a-z])([+-]?(?:\d+(?:\.\d*)?|\.\d+))")
# The lines CAM systems write ("plain" lines), recognised in the upper-cased text of a whole
# program by one multi-line search: an optional block delete and N number, letter-number
# words (no N or O word) separated by blanks, an optional trailing comment. Group 1 is the
# words of a plain line; group 2 is any other line (never empty), which the full parser
# reads when it runs.
_PLAIN_LINE = re.compile(r"^(?:[ \t]*(?:/[ \t]*)?(?:N[0-9]+[ \t]*)?((?:[A-MP-Z][+-]?[0-9.]+[ \t]*)*)"
                         r"(?:\([^()\n]*\)[ \t]*)?(?:;[^\n]*)?$|(.*)$)", re.M)
_LETTERS_TO_BLANKS = str.maketrans(dict.fromkeys("ABCDEFGHIJKLMNOPQRSTUVWXYZ", " "))
_TABLE_CHUNK = 1 << 16  # lines tokenised at a time (bounds the temporary lists)
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
_CONSOLE = frozenset("?!~")
"""Lines that are a controller's console commands (GRBL's status query, feed hold, cycle
start), as a sender's script holds them: skipped like ``$`` commands."""
_DOLLAR_WORD = re.compile(r"\$[+-]?[0-9.]")  # LinuxCNC's spindle selector $n (GRBL: $H, $$, $x=v)
_OWORD = re.compile(r"o(<[^>]*>|\d+)([a-z]+)")
_FUNCTIONS = {
    "abs": abs, "acos": lambda x: math.degrees(math.acos(x)),
    "asin": lambda x: math.degrees(math.asin(x)), "cos": lambda x: math.cos(math.radians(x)),
    "exp": math.exp, "fix": lambda x: float(math.floor(x)), "fup": lambda x: float(math.ceil(x)),
    "ln": math.log, "round": lambda x: float(math.floor(x + 0.5)) if x >= 0 else -float(math.floor(-x + 0.5)),
    "sin": lambda x: math.sin(math.radians(x)), "sqrt": math.sqrt,
    "tan": lambda x: math.tan(math.radians(x)),
}  # fmt: skip
_BINARY = [  # (binding, operators), loosest first
    ("and", "or", "xor"), ("eq", "ne", "gt", "ge", "lt", "le"), ("+", "-"), ("*", "/", "mod"), ("**",),
]
_OP_NAMES = sorted({op for group in _BINARY for op in group if op.isalpha()}, key=len, reverse=True)


def _clean(text: str, source: str, line: int, nested: list | None = None) -> str:
    """Lower case without spaces and comments (LinuxCNC's read_text/close_and_downcase).
    A nested comment ``(a (b) c)``, which LinuxCNC refuses but CAM posts write (Estlcam:
    ``(HSS Twist Drill, 3mm (R))``), is read as one comment and its line appended to
    ``nested`` (the caller warns); without ``nested`` it is refused."""
    out = []
    i, n = 0, len(text)
    while i < n:
        ch = text[i]
        if ch == ";":
            break
        if ch == "(":
            close = text.find(")", i + 1)
            if close < 0:
                raise PathFileError("comment '(' is not closed on this line: close it with ')'",
                                    source, line)
            if "(" in text[i + 1: close]:
                depth, j = 0, i
                while j < n:
                    depth += (text[j] == "(") - (text[j] == ")")
                    if depth == 0:
                        break
                    j += 1
                if depth:
                    raise PathFileError("comment '(' is not closed on this line: close it with ')'",
                                        source, line)
                if nested is None:
                    raise PathFileError("nested comments are not allowed (LinuxCNC refuses them): "
                                        "remove the inner parentheses", source, line)
                nested.append(line)
                close = j
            i = close + 1
            continue
        if ch not in " \t":
            out.append(ch)
        i += 1
    return "".join(out).lower()


class _Parser:
    """Recursive descent over one cleaned line; expressions become small tuples:
    ``("n", value)``, ``("#", expr)``, ``("<", name)``, ``("f", name, expr)``,
    ``("atan", y, x)``, ``("exists", name)``, ``("op", op, a, b)``, ``("neg", a)``."""

    def __init__(self, code: str, source: str, line: int):
        self.s, self.i, self.source, self.line = code, 0, source, line

    def error(self, message: str) -> PathFileError:
        return PathFileError(message, self.source, self.line)

    def peek(self) -> str:
        return self.s[self.i] if self.i < len(self.s) else ""

    def expect(self, ch: str) -> None:
        if self.peek() != ch:
            got = self.s[self.i: self.i + 12] or "end of line"
            raise self.error(f"expected {ch!r} at {got!r}")
        self.i += 1

    def number(self):
        m = _NUMBER.match(self.s, self.i)
        if not m:
            raise self.error(f"expected a number at {self.s[self.i:self.i + 12] or 'end of line'!r}")
        text = m.group()
        if len(text) > MAX_NUMBER_CHARS:
            raise self.error(f"number {text[:16]}... has {len(text)} characters; at most "
                             f"{MAX_NUMBER_CHARS} are read")
        self.i = m.end()
        return ("n", float(text))

    def name(self) -> str:
        self.expect("<")
        close = self.s.find(">", self.i)
        if close < 0:
            raise self.error("named parameter '#<' is not closed with '>'")
        name = self.s[self.i: close]
        self.i = close + 1
        return name

    def parameter(self):
        self.expect("#")
        if self.peek() == "<":
            return ("<", self.name())
        return ("#", self.value())

    def value(self):
        ch = self.peek()
        if ch == "[":
            self.i += 1
            e = self.expression()
            self.expect("]")
            return e
        if ch == "#":
            return self.parameter()
        if ch in "+-" and self.i + 1 < len(self.s) and self.s[self.i + 1] in "#[":
            self.i += 1
            v = self.value()
            return ("neg", v) if ch == "-" else v
        if ch.isalpha():
            for fname in ("atan", "exists", *_FUNCTIONS):
                if self.s.startswith(fname, self.i):
                    self.i += len(fname)
                    if fname == "exists":
                        self.expect("[")
                        self.expect("#")
                        name = self.name()
                        self.expect("]")
                        return ("exists", name)
                    self.expect("[")
                    arg = self.expression()
                    self.expect("]")
                    if fname == "atan":
                        self.expect("/")
                        self.expect("[")
                        x = self.expression()
                        self.expect("]")
                        return ("atan", arg, x)
                    return ("f", fname, arg)
            raise self.error(f"unknown function or word at {self.s[self.i:self.i + 12]!r}")
        return self.number()

    def operator(self, group: tuple):
        for op in group:
            if self.s.startswith(op, self.i) and not (op == "*" and self.s.startswith("**", self.i)):
                return op
        return None

    def expression(self, level: int = 0):
        if level == len(_BINARY):
            return self.value()
        left = self.expression(level + 1)
        while True:
            op = self.operator(_BINARY[level])
            if op is None:
                return left
            self.i += len(op)
            left = ("op", op, left, self.expression(level + 1))

    def words(self):
        """(letter, expr) words and (target, expr) assignments of a machine line."""
        words, assigns = [], []
        while self.i < len(self.s):
            ch = self.peek()
            if ch == "#":
                target = self.parameter()
                self.expect("=")
                assigns.append((target, self.value()))
            elif "a" <= ch <= "z" or ch in "@^$":
                self.i += 1
                words.append((ch, self.value()))
            else:
                raise self.error(f"cannot read {self.s[self.i:self.i + 20]!r}")
        return words, assigns


# ---------------------------------------------------------------------- program
_OWORD_KEYWORDS = {"sub", "endsub", "call", "return", "if", "elseif", "else", "endif", "while",
                   "endwhile", "do", "repeat", "endrepeat", "break", "continue"}
_SYSTEM_PARAMETER_DEFAULTS = {"_value": 0.0, "_value_returned": 0.0}


class Program:
    """A program's lines and the executor that runs them (see :meth:`blocks`).

    Parameters
    ----------
    lines : list of str
        The text, one entry per line (:func:`split_lines`). The plain lines of an
        upper-cased text (words only, as CAM systems write them) are read in bulk when the
        program is made (:class:`WordTable`); any other line is read by the full parser
        when it first runs.
    source : str
        File name for messages.
    system : callable, optional
        ``system(name)`` -> float or None: the value of a read-only global such as ``_x``
        (the motion layer's state); None when it does not know the name.
    """

    def __init__(self, lines: list[str], source: str,
                 system: Callable[[str], float | None] | None = None):
        self.source = source
        self.system = system or (lambda name: None)
        # Parsed lines, by index: every O-word line (found before running, for the jumps of
        # the control flow) and every line the full parser read (kept for loops). Plain
        # lines are read once, in bulk, into the word table: a program of millions of
        # lines costs about 17 bytes per word and 16 per line.
        self.parsed: dict = {}  # index -> ("o", label, kw, args) | ("w", words, assigns) | ("skip", why)
        self.nested_comments: list = []  # lines with a nested comment, read as one comment
        self.called: set = set()  # labels of the subroutines called
        self.search_note = ""  # where subroutine files were looked for (for the error)
        self.olabels: dict = {}  # label -> sorted list of (index, keyword)
        start, stop = 0, len(lines)
        first = next((i for i, t in enumerate(lines) if t.strip()), None)
        if first is not None and lines[first].strip() == "%":
            start = first + 1
            end = next((i for i in range(start, len(lines)) if lines[i].strip() == "%"), None)
            stop = end if end is not None else len(lines)
        self.start, self.stop = start, stop
        self.table = WordTable(lines, start, stop)
        plain = self.table.plain
        self._breaks = np.append(start + np.flatnonzero(~plain[start:stop]), stop)  # non-plain lines
        # the text of the other lines, for the full parser (the plain ones are in the table)
        self.lines = {i: lines[i] for i in self._breaks[:-1].tolist()}
        for i, text in self.lines.items():
            if "o" in text or "O" in text:
                item = self._parse(text, i + 1)
                if item is not None:
                    self.parsed[i] = item
        self.subs = {}
        for label, marks in self.olabels.items():
            for idx, kw in marks:
                if kw == "sub":
                    self.subs[label] = idx
        self.numbered = [0.0] * _N_NUMBERED
        self.globals = dict(_SYSTEM_PARAMETER_DEFAULTS)
        self.frames = [{}]  # named locals per call level
        self.frame_version = 0  # bumped when a parameter of #5160..#5399 is assigned

    # -- parsing
    def _parse(self, text: str, line: int):
        if not text or (len(text) < 3 and not text.strip()):
            return None
        plain = "".join(text.split()).lower()
        if plain.startswith("/"):
            plain = plain[1:]
        if _PLAIN.match(plain) and "(" not in text and ";" not in text:  # fast path
            if not plain:
                return None
            words = []
            for letter, number in _PLAIN_WORD.findall(plain):
                if len(number) > MAX_NUMBER_CHARS:
                    raise PathFileError(f"number {number[:16]}... has {len(number)} characters; "
                                        f"at most {MAX_NUMBER_CHARS} are read", self.source, line)
                words.append((letter, ("n", float(number))))
            return ("w", words, ())
        code = _clean(text, self.source, line, self.nested_comments)
        if code.startswith("/"):
            code = code[1:]
        if not code or code == "%":
            return None
        p = _Parser(code, self.source, line)
        if code.startswith("o"):
            m = _OWORD.match(code)
            if m and m.group(2) in _OWORD_KEYWORDS:
                label, kw = m.group(1), m.group(2)
                p.i = m.end()
                args = []
                while p.i < len(code):
                    if p.peek() != "[" and kw != "call":
                        args.append(p.expression())
                    else:
                        args.append(p.value())
                self.olabels.setdefault(label, []).append((line - 1, kw))
                return ("o", label, kw, tuple(args))
            glued = m and next((k for k in sorted(_OWORD_KEYWORDS, key=len, reverse=True)
                                if m.group(2).startswith(k)), None)
            if glued:  # LinuxCNC's read_o matches the keyword's letters, then refuses the rest
                raise p.error(f"cannot read the O-word {code[:20]!r}: {m.group(2)!r} is not a keyword "
                              f"(LinuxCNC refuses it too); write o{m.group(1)} {glued} with nothing "
                              "glued to the keyword")
            raise p.error(f"cannot read the O-word {code[:20]!r} (expected o<name> or o123 "
                          "followed by sub, call, if, while, ...): write the keyword apart from any "
                          "other word, as o<name> call")
        if (code.startswith("$") and not _DOLLAR_WORD.match(code)) or code in _CONSOLE:
            return ("skip", "console command")
        words, assigns = p.words()
        return ("w", words, tuple(assigns))

    # -- evaluation
    def error(self, message: str, line: int) -> PathFileError:
        return PathFileError(message, self.source, line)

    def get_named(self, name: str, line: int) -> float:
        if name.startswith("_"):
            value = self.system(name)
            if value is not None:
                return value
            if name in self.globals:
                return self.globals[name]
        else:
            for scope in (self.frames[-1],):
                if name in scope:
                    return scope[name]
        if name.startswith(("_hal[", "_ini[")):
            what = "a HAL pin of a running LinuxCNC" if name.startswith("_hal[") else \
                "the INI file of a LinuxCNC configuration"
            raise self.error(f"#<{name}> reads {what}, which a program file alone does not give: "
                             f"replace it with its value (a number) in the program", line)
        raise self.error(f"named parameter #<{name}> is not defined: assign it (#<{name}> = value) "
                         "before this line", line)

    def set_named(self, name: str, value: float) -> None:
        (self.globals if name.startswith("_") else self.frames[-1])[name] = value

    def index(self, value: float, line: int) -> int:
        k = round(value)
        if abs(value - k) > 1e-4 or not 0 <= k < _N_NUMBERED:
            raise self.error(f"parameter number #{value:g} is not an integer in 0..{_N_NUMBERED - 1}", line)
        return k

    def eval(self, e, line: int) -> float:
        kind = e[0]
        if kind == "n":
            return e[1]
        if kind == "#":
            return self.numbered[self.index(self.eval(e[1], line), line)]
        if kind == "<":
            return self.get_named(e[1], line)
        if kind == "neg":
            return -self.eval(e[1], line)
        try:
            if kind == "op":
                a, b = self.eval(e[2], line), self.eval(e[3], line)
                return _apply(e[1], a, b)
            if kind == "f":
                return float(_FUNCTIONS[e[1]](self.eval(e[2], line)))
            if kind == "atan":
                return math.degrees(math.atan2(self.eval(e[1], line), self.eval(e[2], line)))
            if kind == "exists":
                name = e[1]
                scope = self.globals if name.startswith("_") else self.frames[-1]
                return 1.0 if name in scope or (name.startswith("_") and self.system(name) is not None) else 0.0
        except (ValueError, ZeroDivisionError, OverflowError) as exc:
            raise self.error(f"expression cannot be evaluated: {_describe(e)} ({exc})", line) from None
        raise AssertionError(kind)  # pragma: no cover

    def assign(self, target, value: float, line: int) -> None:
        if target[0] == "<":
            self.set_named(target[1], value)
        else:
            k = self.index(self.eval(target[1], line), line)
            self.numbered[k] = value
            if 5160 <= k < 5400:  # home positions, offsets, rotations: the motion layer's frame
                self.frame_version += 1

    # -- execution
    def _next_mark(self, label: str, index: int, kinds: tuple, line: int) -> tuple[int, str]:
        marks = self.olabels.get(label, [])
        j = bisect_right(marks, (index, "~"))
        for idx, kw in marks[j:]:
            if kw in kinds:
                return idx, kw
        raise self.error(f"o{label} has no matching {' / '.join(kinds)}", line)

    def _prev_mark(self, label: str, index: int, kinds: tuple, line: int) -> tuple[int, str]:
        marks = self.olabels.get(label, [])
        j = bisect_right(marks, (index, "")) - 1
        for idx, kw in reversed(marks[:j + 1]):
            if idx < index and kw in kinds:
                return idx, kw
        raise self.error(f"o{label} has no matching {' / '.join(kinds)} before it", line)

    def _is_do_while(self, label: str, index: int) -> bool:
        marks = self.olabels.get(label, [])
        j = bisect_left(marks, (index, ""))  # this while's own mark
        return j > 0 and marks[j - 1][1] == "do"

    def blocks(self, runs: bool = False) -> Iterator[Block | Rows]:
        """Run the program, yielding each executed line that holds machine words.

        Parameters
        ----------
        runs : bool
            Yield each run of consecutive plain lines as one :class:`Rows` (for a reader
            that takes them in bulk) instead of a :class:`Block` per line.
        """
        budget = 10 * (self.stop - self.start) + MAX_EXTRA_BLOCKS
        calls: list = []  # (return index, saved #1-#30, label)
        repeats: dict = {}  # index of a repeat -> remaining count
        pc = self.start
        parsed, numbered, lines, stop = self.parsed, self.numbered, self.lines, self.stop
        table, plain, breaks, row_line = self.table, self.table.plain, self._breaks, self.table.line
        while pc < stop:
            if budget <= 0:
                raise self.error(
                    f"the program executes more than {10 * (self.stop - self.start) + MAX_EXTRA_BLOCKS} "
                    "lines (10 per line of text plus MAX_EXTRA_BLOCKS); an endless loop?", pc + 1)
            if plain[pc]:  # a run of plain lines, up to the next other line
                end = min(int(breaks[np.searchsorted(breaks, pc)]), pc + budget)
                budget -= end - pc
                r0, r1 = row_line.searchsorted((pc + 1, end + 1)).tolist()
                pc = end
                if r1 > r0:
                    if runs:
                        yield Rows(table, r0, r1)
                    else:
                        yield from Rows(table, r0, r1).each()
                continue
            budget -= 1
            item = parsed.get(pc)
            line = pc + 1
            pc += 1
            if item is None:
                item = self._parse(lines[line - 1], line)
                if item is None:
                    continue
                parsed[line - 1] = item
            if item[0] == "w":
                _, words, assigns = item
                ev = self.eval
                g, m, rest = [], [], {}
                for letter, e in words:
                    v = e[1] if e[0] == "n" else ev(e, line)
                    if letter == "g":
                        g.append(v)
                    elif letter == "m":
                        m.append(v)
                    elif letter != "n":
                        u = letter.upper()
                        if u in rest:
                            raise self.error(f"word {u} appears twice", line)
                        rest[u] = v
                if assigns:
                    values = [ev(e, line) for _, e in assigns]
                    for (target, _), v in zip(assigns, values):
                        self.assign(target, v, line)
                if g or m or rest:
                    yield Block(line, tuple(g), tuple(m), rest)
                continue
            if item[0] == "skip":
                yield Block(line, (), (), {"$$": 0.0})
                continue
            _, label, kw, args = item
            here = pc - 1
            if kw == "sub":  # a definition met in the flow: skip its body
                pc = self._next_mark(label, here, ("endsub",), line)[0] + 1
            elif kw == "call":
                if label not in self.subs:
                    raise self.error(f"o{label} call: no subroutine o{label} in this file{self.search_note}: "
                                     f"define it here or put it in a file {label.strip('<>')}.ngc "
                                     "beside the program (or on subroutine_path)", line)
                if len(calls) >= MAX_CALL_DEPTH:
                    raise self.error(f"subroutine calls nested deeper than {MAX_CALL_DEPTH}", line)
                values = [self.eval(a, line) for a in args]
                if len(values) > 30:
                    raise self.error(f"o{label} call with {len(values)} arguments; at most 30", line)
                calls.append((pc, numbered[1:31], label))
                self.called.add(label)
                numbered[1:31] = values + [0.0] * (30 - len(values))
                self.frames.append({})
                self.globals["_value_returned"] = 0.0
                pc = self.subs[label] + 1
            elif kw in ("endsub", "return"):
                if not calls:
                    if kw == "endsub":
                        raise self.error(f"o{label} endsub without its sub", line)
                    raise self.error(f"o{label} return outside a subroutine", line)
                if args:
                    self.globals["_value"] = self.eval(args[0], line)
                    self.globals["_value_returned"] = 1.0
                pc, saved, _ = calls.pop()
                numbered[1:31] = saved
                self.frames.pop()
            elif kw == "if":
                idx = here
                cond = self._cond(args, kw, label, line)
                while not cond:
                    idx, mk = self._next_mark(label, idx, ("elseif", "else", "endif"), line)
                    if mk == "elseif":
                        cond = self._cond(self.parsed[idx][3], mk, label, idx + 1)
                    else:
                        break
                pc = idx + 1
            elif kw in ("elseif", "else"):  # reached at the end of a taken branch
                pc = self._next_mark(label, here, ("endif",), line)[0] + 1
            elif kw == "while":
                if self._is_do_while(label, here):
                    if self._cond(args, kw, label, line):
                        pc = self._prev_mark(label, here, ("do",), line)[0] + 1
                elif not self._cond(args, kw, label, line):
                    pc = self._next_mark(label, here, ("endwhile",), line)[0] + 1
            elif kw == "endwhile":
                pc = self._prev_mark(label, here, ("while",), line)[0]
            elif kw == "repeat":
                if here not in repeats:
                    count = self._cond(args, kw, label, line, number=True)
                    repeats[here] = int(round(count))
                if repeats[here] <= 0:
                    del repeats[here]
                    pc = self._next_mark(label, here, ("endrepeat",), line)[0] + 1
                else:
                    repeats[here] -= 1
            elif kw == "endrepeat":
                pc = self._prev_mark(label, here, ("repeat",), line)[0]
            elif kw == "break":
                idx, mk = self._prev_mark(label, here, ("while", "do", "repeat"), line)
                end = {"while": ("endwhile",), "repeat": ("endrepeat",), "do": ("while",)}[mk]
                repeats.pop(idx, None)
                pc = self._next_mark(label, here, end, line)[0] + 1
            elif kw == "continue":
                idx, mk = self._prev_mark(label, here, ("while", "do", "repeat"), line)
                pc = idx if mk != "do" else self._next_mark(label, here, ("while",), line)[0]
            # do, endif: nothing to do

    def _cond(self, args, kw: str, label: str, line: int, number: bool = False) -> float:
        if len(args) != 1:
            raise self.error(f"o{label} {kw} needs one [expression]", line)
        v = self.eval(args[0], line)
        return v if number else v != 0.0


def _apply(op: str, a: float, b: float) -> float:
    if op == "+":
        return a + b
    if op == "-":
        return a - b
    if op == "*":
        return a * b
    if op == "/":
        return a / b
    if op == "**":
        if a < 0 and b != int(b):
            raise ValueError(f"negative {a:g} raised to the non-integer power {b:g}")
        return float(a**b)
    if op == "mod":
        r = math.fmod(a, b)
        return r + abs(b) if r < 0 else r  # as LinuxCNC's execute_binary1
    if op in ("eq", "ne", "gt", "ge", "lt", "le"):
        return float({"eq": a == b, "ne": a != b, "gt": a > b, "ge": a >= b,
                      "lt": a < b, "le": a <= b}[op])
    if op == "and":
        return float(a != 0.0 and b != 0.0)
    if op == "or":
        return float(a != 0.0 or b != 0.0)
    return float((a != 0.0) != (b != 0.0))  # xor


def _describe(e) -> str:
    kind = e[0]
    if kind == "n":
        return f"{e[1]:g}"
    if kind == "#":
        return f"#{_describe(e[1])}"
    if kind == "<":
        return f"#<{e[1]}>"
    if kind == "neg":
        return f"-{_describe(e[1])}"
    if kind == "op":
        return f"[{_describe(e[2])} {e[1]} {_describe(e[3])}]"
    if kind == "f":
        return f"{e[1]}[{_describe(e[2])}]"
    if kind == "atan":
        return f"atan[{_describe(e[1])}]/[{_describe(e[2])}]"
    return f"exists[#<{e[1]}>]"
