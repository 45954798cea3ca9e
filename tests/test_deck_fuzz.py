"""Fuzzing the deck reader: any text either builds a Model or raises DeckError, never anything else.

Random text, and random mutations of a valid deck (lines dropped, duplicated, swapped, corrupted,
replaced by random tokens), are loaded; the only allowed outcomes are a Model or a DeckError
whose every problem names a file and a line of that deck.
"""
import os
import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lagamine_py.deck import DeckError, load_deck
from lagamine_py.model import Model

VALID = """** fuzz seed: two bodies, contact, parameters, an include, two steps
*HEADING
fuzz seed
*PARAMETER
P = 5
*MESH, NAME=B, TYPE=Q8PE, X0=0, Y0=0, LX=2, LY=1, NX=2, NY=1
*INCLUDE, INPUT=part.inp
*ELEMENT, TYPE=CPE4, ELSET=SQ
100, 101, 102, 103, 104
*NSET, NSET=N1
101, 102
*NSET, NSET=G, GENERATE
1, 5, 2
*ELSET, ELSET=ALL
B, SQ
*SURFACE, NAME=S
SQ, S3
*MATERIAL, NAME=M, LAW=ELASTIC
E=100, NU=0.3
*SOLID, ELSET=ALL, MATERIAL=M, THICKNESS=1
*FOUNDATION, NAME=F
-1, 0
1, 0
3, 0
*CONTACT LAW, NAME=C, TYPE=COULOMB
KP=1e3, KT=1e3, PHI=0.2
*CONTACT, SURFACE=B_BOTTOM, FOUNDATION=F, LAW=C, GAUSS=3
*AMPLITUDE, NAME=A
0, 0, 1, 1
*CHECK, NAME=K, TYPE=COULOMB
PHI=0.2, A=2
*STEP, NAME=ONE, NLGEOM=YES, INC=20
*STATIC
0.5, 1, 1e-3, 0.5
*BOUNDARY
B_LEFT, 1, 2
101, 1, 1, 0.1
*CLOAD, AMPLITUDE=A
N1, 2, -1
*DLOAD
S, P, <P>
*FOUNDATION MOTION, NAME=F
0.1, 0
*OUTPUT, FREQUENCY=1, CONTACT=YES
*CONTROLS
MAXIT=10
*END STEP
*STEP
*STATIC
1, 1
*BOUNDARY, OP=NEW
G, 2, 2, 0
*END STEP
"""

PART = "*NODE, NSET=SQN\n101, 5, 0\n102, 6, 0\n103, 6, 1\n104, 5, 1\n"

TOKENS = ["*", "**", ",", "=", "<P>", "<Q>", "*NODE", "*ELEMENT", "*STEP", "*END STEP", "*STATIC", "*INCLUDE",
          "INPUT=part.inp", "INPUT=fuzz.dat", "TYPE=Q8PE", "TYPE=CPE4", "NAME=B", "ELSET=ALL", "NSET=N1",
          "GENERATE", "1", "-1", "0", "1e999", "nan", "inf", ".5", "1.5D3", "1e-300", "101", "B_LEFT", "S3", "S9",
          "P", "E=1", "NU=0.7", "KP=-1", "x", "\t", " ", "\n", "\r\n", "é", "\x00", "9" * 30]

# DECK_FUZZ_EXAMPLES=5000 for a longer hunt
settings_ = settings(max_examples=int(os.environ.get("DECK_FUZZ_EXAMPLES", 200)), deadline=None,
                     suppress_health_check=list(HealthCheck))


_DIR = tempfile.TemporaryDirectory(prefix="deck_fuzz_")   # one directory, files rewritten per example


def _load(text: str, part: str = PART):
    deck = Path(_DIR.name) / "fuzz.dat"
    deck.write_text(text, encoding="utf-8", errors="surrogatepass")
    (Path(_DIR.name) / "part.inp").write_text(part, encoding="utf-8", errors="surrogatepass")
    try:
        model = load_deck(deck)
    except DeckError as exc:
        assert exc.problems and all(isinstance(p.line, int) and p.file for p in exc.problems)
        return exc
    assert isinstance(model, Model)
    return model


def test_seed_deck_is_valid():
    m = _load(VALID)
    assert isinstance(m, Model) and len(m.steps) == 2 and len(m.blocks) == 2


@settings_
@given(st.text(alphabet=st.sampled_from(sorted(set("*,=<>.-+eEdD0123456789 \t\nabcNODELMSTPX_/\r"))), max_size=300))
def test_random_text(text):
    _load(text)


@settings_
@given(st.lists(st.sampled_from(TOKENS), max_size=60).map("".join))
def test_random_tokens(text):
    _load(text)


_MUTATION = st.one_of(
    st.tuples(st.just("drop"), st.integers(0, 10_000)),
    st.tuples(st.just("dup"), st.integers(0, 10_000)),
    st.tuples(st.just("swap"), st.integers(0, 10_000), st.integers(0, 10_000)),
    st.tuples(st.just("char"), st.integers(0, 10_000), st.integers(0, 80), st.sampled_from(list("*,=<>.-1x \t"))),
    st.tuples(st.just("line"), st.integers(0, 10_000), st.lists(st.sampled_from(TOKENS), max_size=8).map(", ".join)),
)


@settings_
@given(st.lists(_MUTATION, min_size=1, max_size=6), st.booleans())
def test_mutated_valid_deck(mutations, mutate_part):
    lines = (PART if mutate_part else VALID).splitlines()
    for m in mutations:
        k = m[1] % len(lines) if lines else 0
        if not lines:
            lines = [""]
        if m[0] == "drop":
            del lines[k]
        elif m[0] == "dup":
            lines.insert(k, lines[k])
        elif m[0] == "swap":
            j = m[2] % len(lines)
            lines[k], lines[j] = lines[j], lines[k]
        elif m[0] == "char":
            text = lines[k]
            pos = m[2] % (len(text) + 1)
            lines[k] = text[:pos] + m[3] + text[pos + 1:]
        else:
            lines[k] = m[2]
    text = "\n".join(lines) + "\n"
    if mutate_part:
        _load(VALID, text)
    else:
        _load(text)
