"""Mirrored computations of a generated C body run two at a time, in the lanes of a vector.

A humanoid's left and right legs, a quadruped's legs: the articulated-body algorithm does
the same operations on other numbers for each. CasADi writes its SX graphs as scalar C,
one operation a statement, and the C compiler pairs none of them. :func:`pair_lanes`
rewrites the straight-line body of such a function (the form :func:`~workbench.equations.
compiled.generate_c` gives a graph with local variables):

1. every value of the body is hashed by its shape, the operations that make it down to
   the inputs (constants and which input count as leaves, whatever their numbers);
2. outputs of the same shape, not the same value, are paired in the order they come
   (the accelerations of the left and right leg's k-th joints);
3. a pair grows down through the operands (the two values were made by the same
   operation from operands that pair in turn: a constant pair, a value used by both, a
   sine or an input end it) and up through the users (the same operation on paired
   operands), until the legs join what they share;
4. each pair is one operation on ``wb_v2d``, GCC's vector extension of two doubles
   (``vmulpd`` for two ``vmulsd``), whose lanes are read where scalar code uses them.

Each lane runs the IEEE operation the scalar statement ran, on the same operands: the
numbers are the same bit for bit (the flags keep contraction off, :func:`~workbench.
equations.compiled.host_flags`). Only products, sums, differences, quotients,
negations, doublings and squares go into lanes; a body that is not plain assignments, or
where fewer than :data:`MIN_PAIRED_SHARE` of the operations pair, is returned unchanged
(the random trees of the benchmarks: the same C, the same cache key).

Talos (2026-11-27): 3,428 of its 9,985 operations become pair operations, 16,427 -> 11,600
machine instructions (2,070 -> 839 stores to the stack), about 0.72x the time a call
(docs/performance.md).
"""

from __future__ import annotations

import collections
import heapq
import re

SEED_DEPTH = 6  # how deep outputs must have the same shape to be paired
MIN_PAIRED_SHARE = 0.1  # of the body's operations, or the body is left as it was
# GCC's register allocation took 1.6x as long on Talos's body with lanes (7.3-7.6 against
# 4.5-4.9 s CPU, load 4), about 1.15x with the priority algorithm (5.4-5.6 s), which ran it
# as fast (1.90-2.0 against 1.97-2.17 us a call, one process interleaved)
REGISTER_ALLOCATION = "-fira-algorithm=priority"
VECTOR_TYPE = "wb_v2d"
_TYPEDEF = f"typedef double {VECTOR_TYPE} __attribute__((vector_size(16)));"
_ASSIGN = re.compile(r"^  (a\d+)=(.*);$")
_OUTPUT = re.compile(r"^  if \(res\[(\d+)\]!=0\) res\[\d+\]\[(\d+)\]=(a\d+);$")
_VARIABLE = re.compile(r"\ba\d+\b")
_DECLARATION = re.compile(r"^  casadi_real a\d+(, a\d+)*;$")
# what a lane may run: the same IEEE operation on a vector (CasADi's spelling)
_LANE_OPERATIONS = frozenset(
    {"({0}*{1})", "({0}+{1})", "({0}-{1})", "({0}/{1})", "(-{0})", "(2.*{0})", "({0}*{0})"}
)
_SQUARE = "casadi_sq({0})"  # CasADi's helper: x*x


class _Body:
    """A parsed straight-line body: values (template, operand ids) in SSA order, outputs
    (res index, entry, value id)."""

    def __init__(self, values: list[tuple[str, list[int]]], outputs: list[tuple[int, int, int]]):
        self.values, self.outputs = values, outputs

    def kind(self, n: int) -> str:
        template, operands = self.values[n]
        if not operands:
            return "input" if "arg[" in template else "constant"
        return "lane" if template in _LANE_OPERATIONS else "scalar"


def _parse(lines: list[str]) -> _Body | None:
    """The body's values in SSA form (CasADi reuses its variable names), or None if a
    statement is anything but an assignment or an output."""
    values: list[tuple[str, list[int]]] = []
    outputs: list[tuple[int, int, int]] = []
    current: dict[str, int] = {}
    for line in lines:
        if _DECLARATION.match(line) or line == "  return 0;":
            continue
        assign = _ASSIGN.match(line)
        if assign:
            operands: list[int] = []

            def operand(match: re.Match, operands: list[int] = operands) -> str:
                operands.append(current[match.group(0)])
                return f"{{{len(operands) - 1}}}"

            template = _VARIABLE.sub(operand, assign.group(2).replace("{", "{{").replace("}", "}}"))
            if template == _SQUARE:
                template = "({0}*{0})"
            values.append((template, operands))
            current[assign.group(1)] = len(values) - 1
            continue
        output = _OUTPUT.match(line)
        if output is None or output.group(3) not in current:
            return None
        outputs.append((int(output.group(1)), int(output.group(2)), current[output.group(3)]))
    return _Body(values, outputs)


def _shape_hashes(body: _Body, depth: int) -> list[int]:
    """A hash of each value's shape ``depth`` operations deep: its operation and its
    operands' shapes one level less deep, constants and inputs as leaves."""
    leaves = [
        hash(kind if kind in ("constant", "input") else template)
        for (template, _), kind in zip(
            body.values, map(body.kind, range(len(body.values))), strict=True
        )
    ]
    shapes = leaves
    for _ in range(depth):
        shapes = [
            hash((leaf, *(shapes[i] for i in operands)))
            for leaf, (_, operands) in zip(leaves, body.values, strict=True)
        ]
    return shapes


def _seeds(body: _Body) -> list[tuple[int, int]]:
    """Pairs of outputs of the same shape :data:`SEED_DEPTH` operations deep that are not
    the same value, in output order (mirrored limbs come one after the other in a tree's
    order). Deeper, mirrored constants already differ: CasADi folds a product by -1 or a
    sum of a negated value into other operations on one side only."""
    shapes = _shape_hashes(body, SEED_DEPTH)
    groups: dict[int, list[int]] = collections.defaultdict(list)
    for _, _, n in body.outputs:
        if body.kind(n) == "lane" and n not in groups[shapes[n]]:
            groups[shapes[n]].append(n)
    return [(g[k], g[k + 1]) for g in groups.values() for k in range(0, len(g) - 1, 2)]


def _slots(operands: list[int], n: int) -> list[int]:
    """Where ``n`` stands among ``operands``."""
    return [k for k, i in enumerate(operands) if i == n]


def _pairs(body: _Body, seeds: list[tuple[int, int]]) -> dict[tuple[int, int], tuple]:
    """Every pair the seeds grow into: ("lane", template, operand pairs) for a pair run as
    one vector operation, ("pack", ) for a pair whose lanes are made apart (constants,
    inputs, a value both share, other operations)."""
    values = body.values
    pairs: dict[tuple[int, int], tuple] = {}

    def grow_down(root: tuple[int, int]) -> None:
        stack = [(root, False)]
        while stack:
            pair, expanded = stack.pop()
            if pair in pairs and pairs[pair] is not None:
                continue
            a, b = pair
            same = (
                a != b and body.kind(a) == body.kind(b) == "lane" and values[a][0] == values[b][0]
            )
            if not same:
                pairs[pair] = ("pack",)
                continue
            operands = list(zip(values[a][1], values[b][1], strict=True))
            if expanded:
                pairs[pair] = ("lane", values[a][0], operands)
                continue
            pairs[pair] = None  # under way (a DAG: never met again below itself)
            stack.append((pair, True))
            stack.extend((operand, False) for operand in operands)

    for seed in seeds:
        grow_down(seed)
    users: dict[int, list[int]] = collections.defaultdict(list)
    for n, (_, operands) in enumerate(values):
        for i in dict.fromkeys(operands):
            users[i].append(n)
    work = [pair for pair, entry in pairs.items() if entry[0] == "lane"]
    while work:  # grow up: the same operation on paired operands
        a, b = work.pop()
        for user_a in users[a]:
            template = values[user_a][0]
            if body.kind(user_a) != "lane":
                continue
            slots = _slots(values[user_a][1], a)
            matches = [
                u for u in users[b] if values[u][0] == template and _slots(values[u][1], b) == slots
            ]
            if len(matches) != 1 or matches[0] == user_a or (user_a, matches[0]) in pairs:
                continue
            operands = list(zip(values[user_a][1], values[matches[0]][1], strict=True))
            if all(
                (x == y and x not in (a, b))
                or ((x, y) in pairs and pairs[(x, y)][0] == "lane")
                or body.kind(x) == body.kind(y) == "constant"
                for x, y in operands
            ):
                grow_down((user_a, matches[0]))
                work.append((user_a, matches[0]))
    return pairs


def _write(lines_before: list[str], signature: str, body: _Body, pairs: dict) -> list[str]:
    """The new body: scalar values as before (each its own variable), pairs as vector
    operations, in the order of the old body (a pair where its later lane was)."""
    values = body.values
    lanes = [pair for pair, entry in pairs.items() if entry[0] == "lane"]
    lane_of: dict[int, tuple[tuple[int, int], int]] = {}
    for pair in lanes:
        for k, n in enumerate(pair):
            lane_of.setdefault(n, (pair, k))
    scalar: set[int] = set()
    used: set[tuple[int, int]] = set()  # the pairs the outputs need, through scalars or lanes
    stack: list = [n for _, _, n in body.outputs]
    seen: set = set()
    while stack:
        item = stack.pop()
        if item in seen:
            continue
        seen.add(item)
        if isinstance(item, int) and item not in lane_of:
            scalar.add(item)
            stack.extend(values[item][1])
        elif isinstance(item, int):
            stack.append(lane_of[item][0])
        else:
            used.add(item)
            for operand in pairs[item][2]:
                if pairs[operand][0] == "lane":
                    stack.append(operand)
                else:
                    stack.extend(n for n in operand if body.kind(n) != "constant")
    lanes = [pair for pair in lanes if pair in used]

    def needs(n: int) -> tuple:
        return ("s", n) if n in scalar else ("v", lane_of[n][0])

    depends: dict[tuple, set] = {("s", n): {needs(i) for i in values[n][1]} for n in scalar}
    for pair in lanes:
        wanted = set()
        for operand in pairs[pair][2]:
            if pairs[operand][0] == "lane":
                wanted.add(("v", operand))
            else:
                wanted |= {needs(n) for n in set(operand) if body.kind(n) != "constant"}
        depends[("v", pair)] = wanted
    users: dict[tuple, list] = collections.defaultdict(list)
    for item, wanted in depends.items():
        for w in wanted:
            users[w].append(item)
    waiting = {item: len(wanted) for item, wanted in depends.items()}
    ready = [
        (max(item[1]) if item[0] == "v" else item[1], item) for item, w in waiting.items() if not w
    ]
    heapq.heapify(ready)
    order = []
    while ready:
        _, item = heapq.heappop(ready)
        order.append(item)
        for user in users[item]:
            waiting[user] -= 1
            if not waiting[user]:
                heapq.heappush(ready, (max(user[1]) if user[0] == "v" else user[1], user))
    if len(order) != len(depends):
        raise ValueError("pairs depend on each other")
    vector = {pair: f"w{k}" for k, pair in enumerate(lanes)}

    def name(n: int) -> str:
        if n in scalar:
            return f"s{n}"
        pair, k = lane_of[n]
        return f"{vector[pair]}[{k}]"

    def operand(pair: tuple[int, int]) -> str:
        if pairs[pair][0] == "lane":
            return vector[pair]
        parts = [values[n][0] if body.kind(n) == "constant" else name(n) for n in pair]
        return f"(({VECTOR_TYPE}){{{', '.join(parts)}}})"

    out = [signature]
    for kind, item in order:
        if kind == "s":
            template, operands = values[item]
            out.append(f"  casadi_real s{item}=" + template.format(*map(name, operands)) + ";")
        else:
            template = pairs[item][1].replace("2.*", f"(({VECTOR_TYPE}){{{{2., 2.}}}})*")
            operands = map(operand, pairs[item][2])
            out.append(f"  {VECTOR_TYPE} {vector[item]}=" + template.format(*operands) + ";")
    out += [f"  if (res[{r}]!=0) res[{r}][{k}]={name(n)};" for r, k, n in body.outputs]
    return [*lines_before, *out, "  return 0;"]


def compiler_flags(code: str) -> str:
    """Flags to add for ``code`` (" " and :data:`REGISTER_ALLOCATION` if it has lanes)."""
    return f" {REGISTER_ALLOCATION}" if _TYPEDEF in code else ""


def pair_lanes(code: str) -> str:
    """``code`` (CasADi's C of one SX function with local variables) with the operations of
    outputs of the same shape paired into vector lanes (module docstring); ``code`` itself
    if it has no such body or too little pairs."""
    lines = code.split("\n")
    starts = [k for k, line in enumerate(lines) if line.startswith("static int casadi_f")]
    if len(starts) != 1 or "#include <math.h>" not in lines:
        return code
    start = starts[0]
    end = lines.index("}", start)
    body = _parse(lines[start + 1 : end])
    if body is None:
        return code
    pairs = _pairs(body, _seeds(body))
    operations = sum(1 for n in range(len(body.values)) if body.values[n][1])
    paired = sum(1 for entry in pairs.values() if entry[0] == "lane")
    if not paired or paired < MIN_PAIRED_SHARE * operations:
        return code
    try:
        new_body = _write([], lines[start], body, pairs)
    except ValueError:
        return code
    include = lines.index("#include <math.h>")
    before = [*lines[: include + 1], _TYPEDEF, *lines[include + 1 : start]]
    return "\n".join([*before, *new_body, *lines[end:]])
