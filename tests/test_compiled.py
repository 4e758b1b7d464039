"""Formalism option compile=jit: compiled C gives the CasADi VM's numbers, is cached on
disk and reused, and falls back to the VM (with a warning in the run) without a compiler."""

from __future__ import annotations

import dataclasses
import os

import casadi as ca
import numpy as np
import pytest

from workbench.equations import compiled
from workbench.equations.initial import consistent_initial_state
from workbench.execution.execute import RunSpec, clear_cache, execute_run
from workbench.plugin.registry import get_formalism, get_problem


@pytest.fixture(autouse=True)
def cache(tmp_path, monkeypatch):
    """A fresh compile cache and equations cache for every test."""
    monkeypatch.setenv("WORKBENCH_CACHE", str(tmp_path / "cache"))
    clear_cache()
    yield tmp_path / "cache"
    clear_cache()


def build(problem: str, problem_options: dict, formalism: str, options: dict):
    problem_ = get_problem(problem)(problem_options)
    equations = get_formalism(formalism)().build(problem_.model(), options)
    return problem_, equations


def hot_functions(equations, state):
    """(name, function, arguments) of the forms' functions at a perturbed consistent state."""
    rng = np.random.default_rng(3)
    calls = []
    if "ode" in equations.forms:
        y = state.y0(equations, "ode") + 0.1 * rng.standard_normal(equations.forms["ode"].n)
        calls += [("ode.rhs", "ode", "rhs", (0.3, y)), ("ode.jac", "ode", "jacobian", (0.3, y))]
    y, yp = state.y0(equations, "dae"), state.yp0(equations, "dae")
    y = y + 0.1 * rng.standard_normal(y.size)
    calls += [
        ("dae.residual", "dae", "residual", (0.3, y, yp)),
        ("dae.jacobian", "dae", "jacobian", (0.3, y, yp, 7.0)),
    ]
    nq, nv = equations.nq, equations.nv
    q, v = y[:nq], y[nq : nq + nv]
    calls += [
        ("mechanical.mass", "mechanical", "mass", (0.3, q)),
        ("mechanical.forces", "mechanical", "forces", (0.3, q, v)),
    ]
    return calls


CASES = [
    ("spatial-chain", {"n_links": 3}, "recursive"),
    ("binary-tree", {"depth": 2}, "minimal-ode"),
    ("slider-crank", {}, "absolute-dae"),
]


@pytest.mark.parametrize(("problem", "problem_options", "formalism"), CASES)
def test_compiled_evaluation_equals_the_virtual_machine(problem, problem_options, formalism):
    problem_, plain = build(problem, problem_options, formalism, {"compile": "none"})
    _, jit = build(problem, problem_options, formalism, {"compile": "jit"})
    state = consistent_initial_state(plain, problem_)
    for label, form, name, args in hot_functions(plain, state):
        expected = getattr(plain.forms[form], name)(*args)[0]
        function = getattr(jit.forms[form], name)
        value = function(*args)[0]
        assert function.compile(), f"{label} was not compiled: {jit.compile_warnings}"
        assert np.all(np.isfinite(expected)) and np.abs(expected).max() > 0
        np.testing.assert_allclose(value, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    assert jit.compile_warnings == []


def test_the_cache_is_reused_by_a_second_build(cache):
    args = (0.0, np.linspace(0.1, 0.8, 6))
    _, first = build("spatial-chain", {"n_links": 3}, "recursive", {"compile": "jit"})
    before = compiled.STATS.compiled
    expected = first.forms["ode"].rhs(*args)[0]
    assert compiled.STATS.compiled == before + 1  # the first call compiled one library
    # a rewritten library is a new inode (its mtime is touched at each use)
    libraries = {path: path.stat().st_ino for path in cache.glob("*.so")}
    assert len(libraries) == 1

    _, second = build("spatial-chain", {"n_links": 3}, "recursive", {"compile": "jit"})
    loaded = compiled.STATS.loaded
    np.testing.assert_array_equal(second.forms["ode"].rhs(*args)[0], expected)
    assert compiled.STATS.compiled == before + 1, "the second build invoked the compiler"
    assert compiled.STATS.loaded == loaded + 1
    assert {path: path.stat().st_ino for path in cache.glob("*.so")} == libraries

    # other flags are another library
    _, other = build(
        "spatial-chain", {"n_links": 3}, "recursive", {"compile": "jit", "compile_flags": "-O0"}
    )
    np.testing.assert_allclose(other.forms["ode"].rhs(*args)[0], expected, rtol=1e-12)
    assert compiled.STATS.compiled == before + 2 and len(list(cache.glob("*.so"))) == 2


def test_without_a_compiler_jit_falls_back_with_a_warning(monkeypatch, tmp_path):
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    with pytest.warns(compiled.CompileWarning, match="no C compiler"):
        _, equations = build("double-pendulum", {}, "recursive", {"compile": "jit"})
    assert not equations.forms["ode"].rhs.compile()
    assert "no C compiler" in equations.compile_warnings[0]

    spec = RunSpec(
        "double-pendulum", "recursive", "scipy-dop853", 1e-6, 1e-9, {}, {"compile": "jit"}
    )
    with pytest.warns(compiled.CompileWarning):
        row = execute_run(spec, reference_dir=tmp_path).row
    assert row["status"] == "ok"
    assert "no C compiler" in row["message"] and "compile=none" in row["message"]
    assert row["compile_s"] == 0.0


def test_a_graph_that_does_not_compile_stays_in_the_vm_with_a_warning():
    _, equations = build(
        "double-pendulum", {}, "recursive", {"compile": "jit", "compile_flags": "-no-such-flag"}
    )
    with pytest.warns(compiled.CompileWarning, match="stays in the CasADi VM"):
        assert not equations.forms["ode"].rhs.compile()
    (value,) = equations.forms["ode"].rhs(0.0, np.array([0.1, 0.2, 0.0, 0.0]))
    assert np.all(np.isfinite(value))


def test_a_jit_run_measured_in_the_vm_is_warned(tmp_path):
    """A failed compile left the row ok, warning-free and labelled jit: its cost, the VM's,
    stood in the jit pair's place and could be recommended as such."""
    spec = RunSpec("double-pendulum", "recursive", "scipy-dop853", 1e-6, 1e-9, {},
                   {"compile": "jit", "compile_flags": "-no-such-flag"})  # fmt: skip
    with pytest.warns(compiled.CompileWarning):
        row = execute_run(spec, reference_dir=tmp_path).row
    assert row["status"] == "ok"
    assert row["warnings"].startswith("not compiled: compile=jit:")
    assert "(its cost is the VM's)" in row["warnings"]


def test_a_run_with_jit_end_to_end(tmp_path):
    rows = {}
    for mode in ("none", "jit"):
        spec = RunSpec(
            "spatial-chain", "recursive", "scipy-dop853", 1e-8, 1e-11, {"n_links": 3},
            {"compile": mode},
        )  # fmt: skip
        rows[mode] = execute_run(spec, reference_dir=tmp_path).row
    plain, jit = rows["none"], rows["jit"]
    assert plain["status"] == jit["status"] == "ok" and jit["message"] == ""
    assert "not compiled" not in jit["warnings"]
    assert plain["compile_s"] == 0.0 and jit["compile_s"] > 0.0
    assert jit["n_rhs"] == plain["n_rhs"]  # the same numbers give the same steps
    assert jit["err_end"] == pytest.approx(plain["err_end"], rel=1e-6, abs=1e-14)
    assert jit["energy_err_max"] == pytest.approx(plain["energy_err_max"], rel=1e-6, abs=1e-14)


def test_casadi_cvodes_integrates_the_compiled_right_hand_side(tmp_path):
    rows = {}
    for mode in ("none", "jit"):
        spec = RunSpec(
            "spatial-chain", "recursive", "casadi-cvodes", 1e-8, 1e-10, {"n_links": 3},
            {"compile": mode}, {"method": "adams", "iteration": "functional"},
        )  # fmt: skip
        rows[mode] = execute_run(spec, reference_dir=tmp_path).row
    plain, jit = rows["none"], rows["jit"]
    assert plain["status"] == jit["status"] == "ok", jit["message"]
    assert jit["compile_s"] > 0.0 and jit["err_end"] < 1e-5
    assert jit["err_end"] == pytest.approx(plain["err_end"], rel=1e-3)


@pytest.mark.slow
def test_minimal_ode_beyond_the_symbolic_limit_compiles_and_agrees_with_recursive():
    """Above SYMBOLIC_SOLVE_LIMIT M is factorized numerically by CasADi's LDL^T (LAPACK's
    LU cannot be compiled); the accelerations equal the articulated-body algorithm's."""
    _, minimal = build("spatial-chain", {"n_links": 9}, "minimal-ode", {"compile": "jit"})
    _, recursive = build("spatial-chain", {"n_links": 9}, "recursive", {})
    y = np.random.default_rng(0).uniform(-1, 1, 18)
    rhs = minimal.forms["ode"].rhs
    assert rhs.compile(), minimal.compile_warnings
    expected = recursive.forms["ode"].rhs(0.0, y)[0]
    np.testing.assert_allclose(rhs(0.0, y)[0], expected, atol=1e-10 * np.abs(expected).max())


def test_long_bodies_are_split_and_give_the_same_numbers(cache):
    """A 12-link spatial chain's ode right-hand side (~4,000 statements) is compiled as
    parts of a body sharing the work array when above the locals' threshold, whole with
    local variables below it; every output equals the VM's bit for bit either way (the
    same operations in the same order); a body with loops is left whole."""
    import casadi as ca

    from workbench.plugins.formalisms.recursive import ode_function

    function = ode_function(get_problem("spatial-chain")({"n_links": 12}).model())
    code = compiled.generate_c(function, locals_max_instructions=0)  # the work array
    parts = code.count("static void casadi_f0_part")
    # one statement per instruction (inputs, constants, operations, outputs)
    assert parts == -(-function.n_instructions() // compiled.STATEMENTS_PER_PART) > 20
    assert compiled.generate_c(function, 10**9, locals_max_instructions=0).count("_part") == 0
    # below the threshold: local variables, whole (what compile_function compiles here)
    assert function.n_instructions() <= compiled.LOCALS_MAX_INSTRUCTIONS
    assert "_part" not in compiled.generate_c(function) and "w[" not in compiled.generate_c(
        function
    )
    y = np.random.default_rng(5).uniform(-1, 1, 24)
    for locals_max in (0, compiled.LOCALS_MAX_INSTRUCTIONS):
        code = compiled.generate_c(compiled.exported(function), locals_max_instructions=locals_max)
        generated = compiled.generate(function)
        path = compiled.library_path(code, "-O1", generated.compiler, "split")
        loaded = compiled.load_generated(dataclasses.replace(generated, code=code, path=path))
        assert np.array_equal(np.asarray(loaded(0.2, y)), np.asarray(function(0.2, y)))
    x = ca.MX.sym("x", 6, 6)
    looped = compiled.generate_c(ca.Function("looped", [x], [ca.mtimes(x, x)]))
    assert "for (" in looped and compiled.split_long_bodies(looped, 1) == looped


def test_default_flags_small_graphs_at_o2_with_the_cpus_avx_and_the_same_numbers(cache):
    """The default ``compile_flags`` let the workbench choose: a graph with local variables
    (Talos's ABA, here a 12-link chain) at -O2, a larger or MX graph at -O1, and on an
    x86-64 CPU with AVX its three-operand instructions without fused multiply-adds; flags
    of one's own are kept as given. The library's numbers equal the VM's bit for bit."""
    import platform

    from workbench.plugins.formalisms.recursive import ode_function

    function = ode_function(get_problem("spatial-chain")({"n_links": 12}).model())
    generated = compiled.generate(function)
    flags = generated.flags.split()
    assert flags[0] == "-O2" and compiled.uses_locals(function)
    avx = platform.machine().lower() in ("x86_64", "amd64") and "avx" in compiled.cpu_flags()
    assert ("-mavx" in flags and "-ffp-contract=off" in flags) == avx
    assert ("-mavx" in flags) == avx  # never on a CPU without AVX
    x = ca.MX.sym("x", 3)
    assert compiled.default_flags(ca.Function("mx", [x], [x * x])).split()[0] == "-O1"
    assert compiled.generate(function, "-O0").flags == "-O0"
    loaded = compiled.load_generated(generated)
    for y in np.random.default_rng(6).uniform(-2, 2, (5, 24)):
        assert np.array_equal(np.asarray(loaded(0.4, y)), np.asarray(function(0.4, y)))


def test_no_avx_flags_on_a_cpu_without_avx_or_off_x86(monkeypatch):
    """-mavx only where this CPU reports AVX and is x86-64: elsewhere the default flags
    are the optimization level alone (a library is never built for instructions the
    CPU lacks)."""
    import platform

    x = ca.SX.sym("x")
    small = ca.Function("small", [x], [x * x])
    for machine, flags, expected in (
        ("x86_64", frozenset({"sse2", "fma"}), "-O2"),
        ("aarch64", frozenset({"avx"}), "-O2"),
        ("x86_64", frozenset({"sse2", "avx"}), "-O2 -mavx -ffp-contract=off"),
    ):
        monkeypatch.setattr(platform, "machine", lambda machine=machine: machine)
        monkeypatch.setattr(compiled, "cpu_flags", lambda flags=flags: flags)
        compiled.host_flags.cache_clear()
        assert compiled.default_flags(small) == expected
    compiled.host_flags.cache_clear()


def test_the_cache_key_tells_cpu_generations_with_one_name_apart(tmp_path, monkeypatch):
    """A virtual machine names Zen 3 and Zen 5 both "AMD EPYC": a cache in a home folder
    shared by a cluster's nodes must not hand a ``-march=native`` library built on one to
    the other, so the key holds the family, model and instruction-set flags."""
    block = (
        "processor\t: 0\ncpu family\t: {}\nmodel\t\t: {}\nmodel name\t: AMD EPYC\nflags\t\t: {}\n"
    )
    machines = {
        "zen3": block.format(25, 1, "fpu sse2 avx avx2 fma"),
        "zen5": block.format(26, 2, "fpu sse2 avx avx2 fma avx512f"),
        "zen5 without avx-512": block.format(26, 2, "fpu sse2 avx avx2 fma"),
        "zen5 again": block.format(26, 2, "avx512f fma avx2 avx sse2 fpu")
        + "\n"
        + block.format(0, 0, ""),
    }
    paths, read_cpu = {}, compiled.cpu
    for name, text in machines.items():
        (tmp_path / name).write_text(text)
        monkeypatch.setattr(compiled, "cpu", lambda f=str(tmp_path / name): read_cpu(f))
        paths[name] = compiled.library_path("int f(void);", "-O2 -march=native", "cc", "f")
    assert len({paths["zen3"], paths["zen5"], paths["zen5 without avx-512"]}) == 3
    assert paths["zen5"] == paths["zen5 again"]  # flags in any order, the first CPU's block


def compiling_formalisms() -> list[str]:
    """The registered formalisms with a ``compile`` option."""
    from workbench.plugin.registry import plugin_names

    return [
        name
        for name in plugin_names("formalism")
        if "compile" in {f.name for f in dataclasses.fields(get_formalism(name).Options)}
    ]


def catalog_pairs(formalisms: list[str] | None = None):
    """(problem, formalism) for every catalog problem (default options) and every formalism
    of ``formalisms`` (default: all that compile) that takes its model; robots whose files
    are not installed are left out."""
    from workbench.plugin.registry import plugin_names

    pairs = []
    for problem in plugin_names("problem"):
        try:
            model = get_problem(problem)({}).model()
        except Exception:  # noqa: BLE001 - e.g. a robot whose files are not installed
            continue
        pairs += [
            (problem, formalism)
            for formalism in formalisms or compiling_formalisms()
            if not get_formalism(formalism).unsupported(model)
        ]
    return pairs


def catalog_calls(equations, state):
    """(label, form, name, args) of what a catalog check compiles: the right-hand side the
    integrators call most (ode rhs, else the dae residual) and, with constraints, the
    mechanical form's gamma (W v' = gamma: the function whose name clashed with libm)."""
    calls = hot_functions(equations, state)
    first = [c for c in calls if c[0] == "ode.rhs"] or [c for c in calls if c[0] == "dae.residual"]
    q, v = calls[-1][3][1], calls[-1][3][2]
    (gamma,) = equations.forms["mechanical"].acceleration_rhs(0.3, q, v)
    if np.size(gamma):  # a model with constraints
        first.append(("mechanical.gamma", "mechanical", "acceleration_rhs", (0.3, q, v)))
    return first


@pytest.mark.slow
@pytest.mark.timeout(3000)
@pytest.mark.parametrize("formalism", compiling_formalisms())  # one long test was 164-210 s
def test_every_catalog_problem_and_formalism_compiles_and_agrees_with_the_vm(formalism):
    """compile=jit leaves no function in the VM (no libc name clash such as ``gamma``, no
    LAPACK solve CasADi cannot generate C for), and compiled numbers equal the VM's (to
    1e-11 of their size where a numeric KKT solve differs, QR against LU). At -O0, and the
    right-hand side and gamma only (test_compiled_evaluation_equals_the_virtual_machine
    takes every function of three models): what is checked is that C is generated,
    compiles and agrees, in minutes of CI, not its speed."""
    pairs = catalog_pairs([formalism])
    assert len(pairs) > 8, pairs
    failures = []
    for problem, formalism in pairs:
        problem_, plain = build(problem, {}, formalism, {"compile": "none"})
        _, jit = build(problem, {}, formalism, {"compile": "jit", "compile_flags": "-O0"})
        state = consistent_initial_state(plain, problem_)
        for label, form, name, args in catalog_calls(plain, state):
            expected = getattr(plain.forms[form], name)(*args)[0]
            function = getattr(jit.forms[form], name)
            value = function(*args)[0]
            if not function.compile():
                failures.append(f"{problem}/{formalism} {label}: {jit.compile_warnings}")
                continue
            scale = max(float(np.abs(expected).max()), 1.0)
            error = float(np.abs(np.asarray(value) - np.asarray(expected)).max())
            # 1e-11: a compiled numeric KKT solve is CasADi's QR where the VM's is LAPACK's
            # LU (Andrews through recursive: 1.1e-12); every SX graph agrees to the bit
            if not error <= 1e-11 * scale:
                failures.append(f"{problem}/{formalism} {label}: off by {error:.1e}")
        if jit.compile_warnings:
            failures.append(f"{problem}/{formalism}: {jit.compile_warnings}")
    assert failures == []


def test_a_function_named_like_a_libm_function_compiles():
    """CasADi exports a generated function under its name: ``gamma``, ``j0`` or ``y1`` would
    clash with the C library's declarations (``conflicting types for 'gamma'``)."""
    x = ca.SX.sym("x", 2)
    for name in ("gamma", "j0", "y1", "sin"):
        function = ca.Function(name, [x], [ca.vertcat(x[0] * x[1], ca.sin(x[0]))])
        loaded = compiled.compile_function(function)
        expected = np.array([0.3 * 0.7, np.sin(0.3)])
        np.testing.assert_allclose(np.ravel(loaded([0.3, 0.7])), expected, rtol=1e-15)


def test_the_numeric_linear_solvers_the_formalisms_use_compile():
    """Beyond the symbolic-solve limit the KKT system is solved numerically inside the graph:
    with a solver CasADi generates C for (not LAPACK's LU, whose code is an ``#error``)."""
    x = ca.MX.sym("x", 3, 3)
    b = ca.MX.sym("b", 3)
    for method, compiles in (("qr", True), ("ldl", True), ("lapacklu", False)):
        function = ca.Function(f"solve_{method}", [x, b], [ca.solve(x, b, method)])
        if compiles:
            a = np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 2.0]])
            value = np.ravel(compiled.compile_function(function)(a, [1.0, 2.0, 3.0]))
            np.testing.assert_allclose(value, np.linalg.solve(a, [1.0, 2.0, 3.0]), rtol=1e-13)
        else:
            with pytest.raises(RuntimeError, match="#error"):
                compiled.compile_function(function)


def test_a_compile_failure_names_the_compilers_real_error():
    stderr = (
        "code.c: In function 'wb_f':\n"
        "code.c:12:5: warning: unused variable 'w' [-Wunused-variable]\n"
        "code.c:40:1: error: conflicting types for 'gamma'\n"
    )
    assert compiled.compiler_error(stderr) == "code.c:40:1: error: conflicting types for 'gamma'"
    assert compiled.compiler_error("#error LapackLu does not support code generation\n") == (
        "#error LapackLu does not support code generation"
    )
    assert compiled.compiler_error("") == "no output"


def test_the_cache_keeps_the_most_recently_used_libraries_within_its_limit(cache):
    x = ca.SX.sym("x")
    paths = []
    for k in range(4):
        compiled.compile_function(ca.Function(f"f{k}", [x], [x * (k + 1)]))
        paths.append(next(cache.glob(f"wb_f{k}-*.so")))
    size = paths[0].stat().st_size
    for age, path in enumerate(paths):  # f0 oldest ... f3 newest
        os.utime(path, (1e9 + age, 1e9 + age))
    compiled.compile_function(ca.Function("f0", [x], [x * 1]))  # a use makes f0 newest
    removed = compiled.trim_cache(limit=int(2.5 * size))
    assert removed == 2
    assert {p.name for p in cache.glob("*.so")} == {paths[0].name, paths[3].name}
    assert compiled.cache_size() == (2, paths[0].stat().st_size + paths[3].stat().st_size)


def test_the_cache_command_shows_and_clears_the_compiled_libraries(cache):
    from typer.testing import CliRunner

    from workbench.cli import app

    x = ca.SX.sym("x")
    for k in range(2):
        compiled.compile_function(ca.Function(f"g{k}", [x], [x + k]))
    runner = CliRunner()
    shown = runner.invoke(app, ["cache", "info"])
    assert shown.exit_code == 0 and "2 compiled libraries" in shown.output
    assert str(cache) in shown.output.replace("\n", "")
    kept = runner.invoke(app, ["cache", "clear"], input="n\n")
    assert kept.exit_code == 1 and len(list(cache.glob("*.so"))) == 2
    assert "nothing removed" in kept.output
    cleared = runner.invoke(app, ["cache", "clear", "--yes"])
    assert cleared.exit_code == 0 and "removed 2 compiled libraries" in cleared.output
    assert list(cache.glob("*.so")) == []


def test_the_cache_command_says_what_is_wrong_with_its_settings(cache, monkeypatch):
    """A limit that is no number is said (the default is used), a cache path through a
    file is refused in one line, a cache not made yet is said as such."""
    from typer.testing import CliRunner

    from workbench.cli import app

    runner = CliRunner()
    monkeypatch.setenv("WORKBENCH_CACHE_LIMIT_MB", "abc")
    assert compiled.cache_limit_bytes() == compiled.DEFAULT_CACHE_LIMIT_MB * 2**20
    shown = runner.invoke(app, ["cache", "info"])
    assert shown.exit_code == 0, shown.output
    assert "WORKBENCH_CACHE_LIMIT_MB='abc' is not a number of megabytes" in shown.output
    assert "no compiled library yet" in shown.output and not cache.exists()
    monkeypatch.setenv("WORKBENCH_CACHE_LIMIT_MB", "64")
    assert compiled.cache_limit() == (64 * 2**20, "")
    blocker = cache.parent / "a-file"
    blocker.write_text("")
    monkeypatch.setenv("WORKBENCH_CACHE", str(blocker / "cache"))
    out = cache.parent / "out"
    run = ["run", "simple-pendulum", "-f", "recursive", "-i", "rk4", "--out", str(out)]
    sweep = ["sweep", "quick", "--out", str(out)]  # every run failed with it, exit 0
    for command in (["cache", "info"], ["cache", "clear", "--yes"], run, sweep):
        refused = runner.invoke(app, command)
        assert refused.exit_code == 2 and "Traceback" not in refused.output
        assert f"{blocker} is not one (set WORKBENCH_CACHE" in refused.output
    assert not out.exists()


def test_a_compile_block_inside_another_is_counted_once() -> None:
    """The sundials-cvode-c driver counts its loading of the right-hand side's library,
    which counts its own compile: counted twice, the compile stage would exceed the time
    that passed, and the integration (from which it is subtracted) would shrink."""
    import time

    seconds = compiled.STATS.seconds
    start = time.perf_counter()
    with compiled.counted():
        with compiled.counted():
            time.sleep(0.05)
    passed = time.perf_counter() - start
    assert 0.05 <= compiled.STATS.seconds - seconds <= passed
