"""One colour per method, the same in every figure, report and dashboard.

The colours are Okabe and Ito's eight (Okabe & Ito, "Color Universal Design", 2008), chosen to stay
distinguishable under the common colour-vision deficiencies. A colour follows the method's *registry
name*, never its position in a list, so temporal-fusion has one colour in the paper figures, in
`report` and on the dashboard. The paper's key comparison, Proposed (temporal-graph) against Hu
(fu-nonlocal), is blue against orange, the pair that stays apart for deuteranopes and protanopes
(red against green is the pair that does not).

Configurations of one method (temporal-graph with ``variant="paper"`` and tuned) share its hue: the
first keeps the base colour, the others get a darker shade of it (`configuration_colours`). A name
that is not built in (a user's plug-in) gets a colour from a second colour-blind-safe set (Paul Tol's
"muted" scheme) picked by a hash of the name, so it too is stable across runs and outputs.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable

#: Okabe-Ito, by registry name. `none` (the floor) is black: a reference, drawn as a line where a figure can.
METHOD_COLOURS: dict[str, str] = {
    "temporal-graph": "#0072B2",   # blue
    "fu-nonlocal": "#E69F00",      # orange
    "lozes-pde": "#009E73",        # bluish green
    "meshlab": "#CC79A7",          # reddish purple
    "temporal-fusion": "#D55E00",  # vermillion
    "temporal-copy": "#56B4E9",    # sky blue
    "none": "#000000",             # black
}
#: for names not built in: Paul Tol's muted scheme (colour-blind safe), less the greys
EXTRA_COLOURS = ["#332288", "#88CCEE", "#44AA99", "#117733", "#999933", "#DDCC77", "#CC6677", "#882255",
                 "#AA4499"]


def method_colour(name: str) -> str:
    """The colour of a method, by its registry name (``"temporal-graph"``, ``"mypkg.fills:MyFill"``)."""
    if name in METHOD_COLOURS:
        return METHOD_COLOURS[name]
    digest = hashlib.sha256(name.encode("utf-8")).digest()
    return EXTRA_COLOURS[digest[0] % len(EXTRA_COLOURS)]


def shade(colour: str, factor: float) -> str:
    """``colour`` (#RRGGBB) mixed towards black by ``factor`` in [0, 1): ``c' = round(c * (1 - factor))``."""
    if not 0.0 <= factor < 1.0:
        raise ValueError(f"shade factor {factor} is outside [0, 1)")
    rgb = [int(colour[i:i + 2], 16) for i in (1, 3, 5)]
    return "#" + "".join(f"{round(c * (1.0 - factor)):02X}" for c in rgb)


def configuration_colours(configurations: Iterable[tuple[str, str]]) -> dict[str, str]:
    """A colour per (label, registry name): a method's first configuration (in the order given) gets the
    method's colour, its second and later ones darker shades of it (35 %, then 55 %, 70 %)."""
    shades = [0.0, 0.35, 0.55, 0.7]
    seen: dict[str, int] = {}
    colours: dict[str, str] = {}
    for label, name in configurations:
        if label in colours:
            continue
        k = seen.get(name, 0)
        seen[name] = k + 1
        colours[label] = shade(method_colour(name), shades[min(k, len(shades) - 1)])
    return colours
