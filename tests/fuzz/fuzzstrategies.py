"""Hypothesis strategies of the fuzz campaign: one perturbation of one argument of one entry
point (fuzzcases.ENTRIES), by family.

Families:

* ``form``      the same values in another container or dtype: list, float32, int, Fortran
  order, strided, negative stride, read-only, big-endian, pandas, masked arrays (with and
  without masked entries), float16, longdouble, bool, object, complex, strings, None, ragged;
* ``value``     a special value at one position: NaN, ±inf, ±1e300, 1e-300, subnormal, 1e155
  (whose square overflows), alone or mirrored across the diagonal of a covariance;
* ``structure`` covariances that are not symmetric, indefinite, zero or huge;
* ``shape``     wrong shapes: transposed, reshaped, a dimension dropped, added, grown, shrunk
  or zero, unit dimensions (which may be accepted: then the result must be that of the
  right shape);
* ``scalar``    integers (numpy integers, negative, 1.5, bool, str, NaN, 2**31 ... 10**100),
  floats (NaN, inf, negative, zero, 1e±300, str, complex, lists), strings (bytes, case, empty),
  booleans, ``outputs=``, EM's ``fit=``, models and callables.

The expectation of each variant is fixed here from the documentation, never from what kfast
does today (see fuzzcases.Case).
"""

from __future__ import annotations

import math

from hypothesis import strategies as st

from fuzzcases import ENTRIES, Arg, Case, Entry

SPECIALS = ("nan", "inf", "-inf", "1e300", "-1e300", "1e-300", "5e-324", "1e155", "-1e155")

# name: (template over {a}, expectation, must_accept, ndim >= this, reference)
FORMS = {
    "list": ("np.asarray({a}).tolist()", "equal", True, 0),
    "float32": ("np.asarray({a}, dtype=np.float32)", "equal", True, 0),
    "int64": ("np.round(np.asarray({a}) * 4).astype(np.int64)", "equal", True, 0),
    "uint8": ("np.abs(np.round(np.asarray({a}) * 4)).astype(np.uint8)", "equal", True, 0),
    "fortran": ("np.asfortranarray({a})", "equal", True, 2),
    "strided": ("np.repeat(np.asarray({a}), 2, axis=-1)[..., ::2]", "equal", True, 1),
    "negative-stride": ("np.asarray({a})[::-1].copy()[::-1]", "equal", True, 1),
    "read-only": ("(_ro := np.array({a}), _ro.setflags(write=False))[0]", "equal", True, 0),
    "big-endian": ("np.asarray({a}, dtype='>f8')", "equal", True, 0),
    "pandas": (None, "equal", True, 1),
    "masked-none": ("np.ma.masked_array({a}, mask=False)", "equal", False, 0),
    "masked": ("np.ma.masked_array({a}, mask=np.arange(np.size({a})).reshape(np.shape({a})) == {i})", "either", False, 0),
    "float16": ("np.asarray({a}, dtype=np.float16)", "equal", False, 0),
    "longdouble": ("np.asarray({a}, dtype=np.longdouble)", "equal", False, 0),
    "matrix": ("np.asmatrix({a})", "equal", False, 2),
    "bool": ("np.asarray({a}) != 0", "either", False, 0),
    "object": ("np.asarray({a}, dtype=object)", "either", False, 0),
    "complex-zero-imag": ("np.asarray({a}, dtype=complex)", "either", False, 0),
    "complex": ("np.asarray({a}) + 1j", "error", False, 0),
    "str": ("np.asarray({a}).astype(str)", "error", False, 0),
    "None": ("None", "error", False, 0),
    "ragged": ("[[1.0], [1.0, 2.0]]", "error", False, 0),
    "dict": ("{{'a': 1.0}}", "error", False, 0),
}


def _make(entry: Entry, arg: Arg, expr: str, family: str, variant: str, expect: str, must_accept=False, reference=None) -> Case:
    args = entry.good_args()
    args[arg.name] = expr
    return Case(
        entry=entry.name,
        fixture=entry.fixture,
        args=tuple(args.items()),
        perturbed=arg.name,
        names=arg.error_names,
        family=family,
        variant=variant,
        expect=expect,
        must_accept=must_accept,
        reference=reference,
        validator=entry.validator,
    )


def _array_args(entry: Entry, cov_only=False) -> list:
    return [a for a in entry.args if a.kind == "array" and (a.cov or not cov_only)]


def form_names(arg: Arg) -> list:
    ndim = len(arg.shape)
    return [k for k, v in FORMS.items() if ndim >= v[3] and not (k == "pandas" and ndim > 2) and not (k == "matrix" and ndim != 2)]


def form_case_for(entry: Entry, arg: Arg, form: str, i: int = 0) -> Case:
    ndim = len(arg.shape)
    template, expect, must, _ = FORMS[form]
    if form == "pandas":
        template = "pd.Series({a})" if ndim == 1 else "pd.DataFrame({a})"
    expr = template.format(a=arg.good, i=i)
    if (arg.optional or arg.none_ok) and form == "None":
        return _make(entry, arg, expr, "form", form, "either")
    if entry.complex_model and form in ("complex", "complex-zero-imag"):
        # A complex matrix makes a complex-valued model (kfast.linear.complex), or is refused
        # naming the argument (e.g. a complex A of from_continuous).
        return _make(entry, arg, expr, "form", form, "either")
    if entry.complex_ok and form == "complex":
        # A complex equation: solved, or refused naming the argument (a non-Hermitian q, r).
        return _make(entry, arg, expr, "form", form, "either")
    reference = "canonical" if expect in ("equal", "either") else None
    return _make(entry, arg, expr, "form", form, expect, must, reference)


def all_form_cases(entry: Entry) -> list:
    """Every form of every array argument (the masked entry in the middle)."""
    return [form_case_for(entry, a, f, math.prod(a.shape) // 2) for a in _array_args(entry) for f in form_names(a)]


@st.composite
def form_case(draw, entry: Entry) -> Case:
    arg = draw(st.sampled_from(_array_args(entry)))
    form = draw(st.sampled_from(form_names(arg)))
    i = draw(st.integers(0, max(0, math.prod(arg.shape) - 1)))
    return form_case_for(entry, arg, form, i)


@st.composite
def value_case(draw, entry: Entry) -> Case:
    arg = draw(st.sampled_from(_array_args(entry)))
    special = draw(st.sampled_from(SPECIALS))
    size = max(1, math.prod(arg.shape))
    i = draw(st.integers(0, size - 1))
    if arg.cov and len(arg.shape) >= 2 and draw(st.booleans()):
        n = arg.shape[-1]
        r, c = divmod(i % (n * n), n)
        expr = f"(_v := np.array({arg.good}, dtype=float), _v.__setitem__((..., {r}, {c}), {special}), _v.__setitem__((..., {c}, {r}), {special}))[0]"
        variant = f"{special} at [{r},{c}] and [{c},{r}]"
    else:
        expr = f"(_v := np.array({arg.good}, dtype=float), np.put(_v, {i}, {special}))[0]"
        variant = f"{special} at flat {i}"
    return _make(entry, arg, expr, "value", variant, "either")


@st.composite
def structure_case(draw, entry: Entry) -> Case:
    arg = draw(st.sampled_from(_array_args(entry, cov_only=True)))
    n = arg.shape[-1] if arg.shape else 1
    options = {
        "indefinite": (f"np.asarray({arg.good}) - 10.0 * np.eye({n})", "error"),
        "negative-diagonal": (f"(_v := np.array({arg.good}, dtype=float), _v.__setitem__((..., 0, 0), -1e-3))[0]", "error"),
        "zero": (f"0.0 * np.asarray({arg.good})", "either"),
        "huge": (f"1e300 * np.asarray({arg.good})", "either"),
        "tiny": (f"1e-300 * np.asarray({arg.good})", "either"),
        "near-singular": (f"np.asarray({arg.good}) * 0 + np.ones(({n}, {n})) + 1e-15 * np.eye({n})", "either"),
    }
    if n >= 2:
        options["asymmetric"] = (f"(_v := np.array({arg.good}, dtype=float), _v.__setitem__((..., 0, {n - 1}), _v[..., 0, {n - 1}] + 0.1))[0]", "error")
        options["asymmetric-1e-14"] = (f"(_v := np.array({arg.good}, dtype=float), _v.__setitem__((..., 0, {n - 1}), _v[..., 0, {n - 1}] * (1 + 1e-14)))[0]", "either")
    if not arg.shape:
        options["negative-diagonal"] = ("-1e-3", "error")
    variant = draw(st.sampled_from(sorted(options)))
    expr, expect = options[variant]
    return _make(entry, arg, expr, "structure", variant, expect)


def _shape_candidates(arg: Arg) -> list:
    """(shape, expectation, how) for wrong shapes of ``arg``. A shape that differs from the
    right one only by unit dimensions (same size) may be accepted, with the result of the right
    shape; a per-step stack (a leading axis on a model matrix) and another length of a free
    first axis are valid; everything else must be refused."""
    s = tuple(arg.shape)
    out = {}
    size = math.prod(s)

    def add(shape, expect, how):
        shape = tuple(shape)
        if shape == s or shape in arg.alt_shapes or shape in out:
            return
        if arg.stackable and len(shape) == len(s) + 1 and shape[1:] == s:
            return  # a per-step stack: valid
        if math.prod(shape) == size and [d for d in shape if d != 1] == [d for d in s if d != 1]:
            expect, how = "either", "reshaped"
        elif arg.free_length and len(shape) == len(s) and len(s) >= 1 and shape[1:] == s[1:]:
            expect = "either"
        out[shape] = (expect, how)

    add(s[::-1], "error", "reshaped")  # a transpose or reshape of another layout
    for d in range(len(s)):
        add(s[:d] + s[d + 1 :], "error", "full")
        add(s[:d] + (s[d] + 1,) + s[d + 1 :], "error", "full")
        if s[d] > 1:
            add(s[:d] + (s[d] - 1,) + s[d + 1 :], "error", "full")
        add(s[:d] + (0,) + s[d + 1 :], "error", "full")
    add((2,) + s, "error", "full")
    add(s + (2,), "error", "full")
    add((1,) + s, "either", "reshaped")
    add(s + (1,), "either", "reshaped")
    if len(s) >= 2:
        add((size,), "error", "reshaped")
    if not s:
        add((2,), "error", "full")
        add((0,), "error", "full")
    return [(k,) + v for k, v in out.items()]


@st.composite
def shape_case(draw, entry: Entry) -> Case:
    arg = draw(st.sampled_from([a for a in _array_args(entry) if a.shape is not None]))
    shape, expect, how = draw(st.sampled_from(_shape_candidates(arg)))
    s = tuple(arg.shape)
    transposed = len(s) == 2 and shape == s[::-1]
    if transposed:
        expr = f"np.transpose({arg.good})"
    elif how == "reshaped":
        expr = f"np.reshape({arg.good}, {shape})"
    else:
        expr = f"np.full({shape}, 0.5)"
    reference = {arg.name: f"np.reshape({expr}, {s})"} if (expect == "either" and how == "reshaped") else None
    return _make(entry, arg, expr, "shape", f"{shape} ({'transposed' if transposed else how})", expect, reference=reference)


# The integers of the issue (2**62 and 10**10 for sizes, steps, lags and threads) are tried in
# every profile; the other huge ones (which may each cost a timeout while kfast hangs on them)
# only in the long profile.
LONG_ONLY = {"2**31", "2**63", "2**64", "10**100", "np.int64(2**62)", "np.uint64(2**64 - 1)", "10**400"}

INT_VARIANTS = [
    # (expression over {g}, expectation, reference)
    ("np.int64({g})", "equal", "good"),
    ("np.int32({g})", "equal", "good"),
    ("np.uint16({g})", "equal", "good"),
    ("0", "either", None),
    ("-1", "error", None),
    ("1.5", "error", None),
    ("float({g})", "either", "good"),
    ("True", "either", None),
    ("'3'", "error", None),
    ("None", "either", None),
    ("float('nan')", "error", None),
    ("[{g}]", "either", None),
    ("2**31", "either", "huge"),
    ("10**10", "either", "huge"),
    ("2**62", "either", "huge"),
    ("2**63", "either", "huge"),
    ("2**64", "either", "huge"),
    ("10**100", "either", "huge"),
    ("-2**63", "error", None),
    ("np.int64(2**62)", "either", "huge"),
    ("np.uint64(2**64 - 1)", "either", "huge"),
]
FLOAT_VARIANTS = [
    ("np.float64({g})", "equal", "good"),
    ("np.array({g})", "equal", "good"),
    ("np.float32({g})", "either", "canonical"),
    ("nan", "either", None),
    ("inf", "either", None),
    ("-inf", "either", None),
    ("-1.0", "either", None),
    ("0.0", "either", None),
    ("1e-300", "either", None),
    ("1e300", "either", None),
    ("'1'", "either", None),
    ("True", "either", None),
    ("1 + 1j", "error", None),
    ("[{g}, {g}]", "either", None),
    ("[]", "either", None),
    ("None", "either", None),
    ("10**400", "either", None),
]
STR_VARIANTS = [
    ("np.str_({g})", "equal", "good"),
    ("{g}.upper()", "either", None),
    ("{g}.encode()", "error", None),
    ("''", "error", None),
    ("None", "either", None),
    ("1", "error", None),
    ("[{g}]", "error", None),
    ("{g} + ' '", "either", None),
]
BOOL_VARIANTS = [
    ("np.bool_({g})", "equal", "good"),
    ("int({g})", "either", None),
    ("'no'", "either", None),
    ("None", "either", None),
    ("2", "either", None),
    ("[]", "either", None),
]
OUTPUTS_VARIANTS = [("'x_filt'", "either", None), ("('nope',)", "error", None), ("5", "error", None), ("[None]", "error", None),
                    ("b'x_filt'", "either", None), ("()", "either", None), ("['x_filt', 'x_filt']", "either", None)]
FIT_VARIANTS = [("None", "either", None), ("'F'", "either", None), ("('X',)", "error", None), ("()", "either", None),
                ("['F', 'F']", "either", None), ("5", "either", None), ("('x0', 'P0')", "either", None)]
SEED_VARIANTS = [("np.int64(0)", "equal", "good"), ("np.random.default_rng(0)", "either", None), ("-1", "either", None),
                 ("1.5", "either", None), ("'x'", "either", None), ("2**70", "either", None), ("None", "either", None),
                 ("[1, 2]", "either", None), ("nan", "either", None)]
OBJECT_VARIANTS = {
    "model": [("None", "error", None), ("5", "error", None), ("M._core", "either", "good"),
              ("kfast.models.ar([0.5], 1.0)", "error", None), ("'M'", "error", None),
              ("kfast.LinearGaussian(F=np.stack([0.9 * np.eye(3)] * 6), H=np.eye(2, 3), Q=np.eye(3), R=np.eye(2), "
               "B=np.ones((3, 2)), D=np.ones((2, 2)))", "either", None)],
    "build": [("None", "error", None), ("5", "error", None), ("lambda th: None", "error", None),
              ("lambda th: (kfast.LinearGaussian(F=0.8, H=1.0, Q=1.0, R=1.0), 0.0)", "error", None),
              ("lambda th: (kfast.LinearGaussian(F=0.8, H=1.0, Q=np.exp(th[0]), R=1.0), 0.0, nan)", "either", None),
              ("lambda th: (kfast.LinearGaussian(F=0.8, H=1.0, Q=th[0], R=1.0), 0.0, 1.0)", "either", None)],
}
SCALAR_TABLES = {"int": INT_VARIANTS, "float": FLOAT_VARIANTS, "str": STR_VARIANTS, "bool": BOOL_VARIANTS,
                 "outputs": OUTPUTS_VARIANTS, "fit": FIT_VARIANTS, "seed": SEED_VARIANTS}


def scalar_variants(arg: Arg, long: bool = True) -> list:
    if arg.kind == "object":
        return OBJECT_VARIANTS.get(arg.name, OBJECT_VARIANTS["model"])
    return [v for v in SCALAR_TABLES[arg.kind] if long or v[0] not in LONG_ONLY]


def scalar_case_for(entry: Entry, arg: Arg, variant) -> Case:
    template, expect, ref = variant
    g = arg.good
    expr = template.format(g=g)
    if g == "None" and "{g}" in template:
        expr = template.replace("{g}", "1e-9")
    reference = None
    if ref == "good":
        reference = {arg.name: g}
    elif ref == "canonical":
        reference = "canonical"
    elif ref == "huge" and arg.huge_reference is not None:
        reference = {arg.name: arg.huge_reference}
    return _make(entry, arg, expr, "scalar", template.format(g="g"), expect, expect == "equal", reference)


@st.composite
def scalar_case(draw, entry: Entry) -> Case:
    arg = draw(st.sampled_from([a for a in entry.args if a.kind != "array"]))
    variant = draw(st.sampled_from(scalar_variants(arg)))
    return scalar_case_for(entry, arg, variant)


FAMILIES = {"form": form_case, "value": value_case, "structure": structure_case, "shape": shape_case, "scalar": scalar_case}


def families_of(entry: Entry) -> list:
    out = []
    if any(a.kind == "expression" for a in entry.args):
        return out
    if entry.raw:
        return ["shape"]
    if _array_args(entry):
        out += ["form", "value", "shape"]
    if _array_args(entry, cov_only=True):
        out.append("structure")
    if any(a.kind != "array" for a in entry.args):
        out.append("scalar")
    return out
