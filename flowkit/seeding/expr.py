"""A small expression language for ``where:EXPR:n`` seeds: comparisons of scalar fields joined by
boolean operators, parsed by recursive descent and evaluated on arrays (never ``eval``).

    expr    := or
    or      := and (("or" | "|") and)*
    and     := not (("and" | "&") not)*
    not     := ("not" | "!") not | compare
    compare := operand (("<" | "<=" | ">" | ">=" | "==" | "!=") operand)+  |  "(" expr ")"
    operand := NAME | NUMBER | "-" NUMBER

A chain ``300 < T <= 302`` means ``300 < T and T <= 302``.  Anything else (arithmetic, calls,
attributes, strings) is refused with an error that names the token and its position.

Evaluation runs on point values (``evaluate``) or on per-cell value intervals
(``evaluate_interval``: True, False or None for "maybe" per cell), which tells the seeder which
cells can hold a point where the expression holds, so it draws only there.
"""

from __future__ import annotations

import re

import numpy as np

COMPARISONS = ("<=", ">=", "==", "!=", "<", ">")
_TOKEN = re.compile(r"\s*(?:(?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)"
                    r"|(?P<name>[A-Za-z_][A-Za-z0-9_]*)"
                    r"|(?P<op><=|>=|==|!=|<|>|\(|\)|&|\||!|-))")


class ExpressionError(ValueError):
    """An expression that is not allowed; the message names the bad token."""


def tokenize(text: str) -> list[tuple[str, str, int]]:
    """(kind, text, position) per token: kind num, name, op, or word (and, or, not)."""
    out, i = [], 0
    while i < len(text):
        if text[i].isspace():
            i += 1
            continue
        m = _TOKEN.match(text, i)
        if m is None or m.end() == i:
            tok = text[i]  # names and numbers always match: the bad token is this character
            raise ExpressionError(f"expression {text!r}: token {tok!r} at position {i} is not "
                                  "allowed (only scalar field names, numbers, < <= > >= == !=, "
                                  "and or not, & | !, parentheses)")
        kind = m.lastgroup
        tok, pos = m.group(kind), m.start(kind)
        if kind == "name" and tok.lower() in ("and", "or", "not"):
            kind, tok = "word", tok.lower()
        out.append((kind, tok, pos))
        i = m.end()
    return out


class Expression:
    """A parsed expression; ``names`` are the fields it reads."""

    def __init__(self, text: str, allowed_names=None):
        self.text = text
        self._toks = tokenize(text)
        self._i = 0
        self.names: set[str] = set()
        self._allowed = None if allowed_names is None else set(allowed_names)
        if not self._toks:
            raise ExpressionError(f"expression {text!r}: empty")
        self.tree = self._or()
        if self._i < len(self._toks):
            self._bad(self._toks[self._i], "is not expected here")

    # -- parsing -------------------------------------------------------------------------------
    def _bad(self, tok, why):
        raise ExpressionError(f"expression {self.text!r}: token {tok[1]!r} at position {tok[2]} "
                              f"{why}")

    def _peek(self):
        return self._toks[self._i] if self._i < len(self._toks) else None

    def _take(self):
        tok = self._peek()
        if tok is None:
            raise ExpressionError(f"expression {self.text!r}: ends too early")
        self._i += 1
        return tok

    def _is(self, *texts):
        tok = self._peek()
        return tok is not None and tok[1] in texts and tok[0] in ("op", "word")

    def _chain(self, sub, words, kind):
        node = sub()
        while self._is(*words):
            self._take()
            node = (kind, node, sub())
        return node

    def _or(self):
        return self._chain(self._and, ("or", "|"), "or")

    def _and(self):
        return self._chain(self._not, ("and", "&"), "and")

    def _not(self):
        if self._is("not", "!"):
            self._take()
            return ("not", self._not())
        return self._compare()

    def _compare(self):
        if self._is("("):
            self._take()
            node = self._or()
            tok = self._take()
            if tok[1] != ")":
                self._bad(tok, "is not expected here (a ')' is missing)")
            return node
        left = self._operand()
        terms = []
        while self._is(*COMPARISONS):
            op = self._take()[1]
            right = self._operand()
            terms.append(("cmp", op, left, right))
            left = right
        if not terms:
            tok = self._peek()
            if tok is None:
                raise ExpressionError(f"expression {self.text!r}: {left[1]!r} is not compared "
                                      "with anything (e.g. T > 302)")
            self._bad(tok, "is not allowed here (expected a comparison: < <= > >= == !=)")
        node = terms[0]
        for t in terms[1:]:
            node = ("and", node, t)
        return node

    def _operand(self):
        tok = self._take()
        if tok[0] == "num":
            return ("num", float(tok[1]))
        if tok[1] == "-":
            nxt = self._take()
            if nxt[0] != "num":
                self._bad(nxt, "is not allowed after '-' (only a number may be negated)")
            return ("num", -float(nxt[1]))
        if tok[0] == "name":
            if self._allowed is not None and tok[1] not in self._allowed:
                have = ", ".join(sorted(self._allowed)) or "none"
                self._bad(tok, f"is not a scalar field of the data (available: {have})")
            self.names.add(tok[1])
            return ("name", tok[1])
        self._bad(tok, "is not allowed here (expected a scalar field name or a number)")

    # -- evaluation ----------------------------------------------------------------------------
    def evaluate(self, values: dict) -> np.ndarray:
        """Boolean array: the expression on point values ``values[name]`` (NaN compares False)."""
        return np.asarray(self._eval(self.tree, values), bool)

    def _eval(self, node, v):
        kind = node[0]
        if kind == "or":
            return self._eval(node[1], v) | self._eval(node[2], v)
        if kind == "and":
            return self._eval(node[1], v) & self._eval(node[2], v)
        if kind == "not":
            return ~self._eval(node[1], v)
        _, op, a, b = node
        x, y = self._value(a, v), self._value(b, v)
        with np.errstate(invalid="ignore"):
            r = {"<": x < y, "<=": x <= y, ">": x > y, ">=": x >= y, "==": x == y,
                 "!=": x != y}[op]
        return r & np.isfinite(x) & np.isfinite(y)

    @staticmethod
    def _value(node, v):
        return np.asarray(node[1] if node[0] == "num" else v[node[1]], np.float64)

    def evaluate_interval(self, lo: dict, hi: dict) -> tuple[np.ndarray, np.ndarray]:
        """(surely, maybe) boolean arrays per cell, for values known to lie in [lo, hi]: where
        ``maybe`` is False the expression holds nowhere in the cell."""
        return self._interval(self.tree, lo, hi)

    def _interval(self, node, lo, hi):
        kind = node[0]
        if kind in ("or", "and"):
            s1, m1 = self._interval(node[1], lo, hi)
            s2, m2 = self._interval(node[2], lo, hi)
            return (s1 | s2, m1 | m2) if kind == "or" else (s1 & s2, m1 & m2)
        if kind == "not":
            s, m = self._interval(node[1], lo, hi)
            return ~m, ~s
        _, op, a, b = node
        al, ah = self._value(a, lo), self._value(a, hi)
        bl, bh = self._value(b, lo), self._value(b, hi)
        with np.errstate(invalid="ignore"):
            if op in ("<", "<="):
                lt = (ah < bl) if op == "<" else (ah <= bl)
                surely, maybe = lt, (al < bh) if op == "<" else (al <= bh)
            elif op in (">", ">="):
                surely = (al > bh) if op == ">" else (al >= bh)
                maybe = (ah > bl) if op == ">" else (ah >= bl)
            elif op == "==":
                surely = (al == ah) & (bl == bh) & (al == bl)
                maybe = (al <= bh) & (bl <= ah)
            else:  # !=
                surely = (ah < bl) | (bh < al)
                maybe = ~((al == ah) & (bl == bh) & (al == bl))
        finite = np.isfinite(al) & np.isfinite(ah) & np.isfinite(bl) & np.isfinite(bh)
        return surely & finite, maybe & finite
