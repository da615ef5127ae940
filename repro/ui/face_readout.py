"""The blendshape panel's readouts (Lewis et al. 2005, Section 5): its numbers line and the same in words.

The numbers are those of :func:`repro.blendshapes.scenarios.evaluate`: the motion of the
selection and how faithfully the rest of the face follows the sliders.  The numbers line
(:data:`NUMBERS_FORMAT`, stable and parseable: :func:`parse_numbers`) sits behind the
panel's "details" toggle; :func:`face_readout` says it in words, always shown.
"""

from __future__ import annotations

import numpy as np

from repro.ui.panel import parse_numbers_line

__all__ = ["NUMBERS_FORMAT", "NOT_APPLICABLE", "face_readout", "format_numbers", "parse_numbers"]

#: The text of the panel's numbers line (plain text; :func:`parse_numbers` reads it back).
NUMBERS_FORMAT = (
    "selected motion: {selected_motion:.6g} | unselected fidelity: {unselected_fidelity:.6g} "
    "| alpha: {alpha:.6g} | attenuation: {attenuation}"
)
#: the numbers line's unselected fidelity when the sliders intend no motion of the rest (0/0): no number
NOT_APPLICABLE = "n/a"


def format_numbers(numbers: dict) -> str:
    """The numbers line (:data:`NUMBERS_FORMAT`), with :data:`NOT_APPLICABLE` for a fidelity that is no number."""
    if np.isfinite(numbers["unselected_fidelity"]):
        return NUMBERS_FORMAT.format(**numbers)
    return NUMBERS_FORMAT.replace("{unselected_fidelity:.6g}", NOT_APPLICABLE).format(**numbers)


_NUMBER_FIELDS = {
    "selected motion": "selected_motion",
    "unselected fidelity": "unselected_fidelity",
    "alpha": "alpha",
    "attenuation": "attenuation",
}


def parse_numbers(text: str) -> dict:
    """The panel's numbers line (:data:`NUMBERS_FORMAT`) as a dict of floats (and ``attenuation``).

    ``parse_numbers("selected motion: 0.0837 | unselected fidelity: 0.547 | alpha: 335 | attenuation: on")``
    gives ``{"selected_motion": 0.0837, "unselected_fidelity": 0.547, "alpha": 335.0, "attenuation": "on"}``.
    Raises ``ValueError`` for anything else (e.g. an ``error: ...`` line).
    """
    out = parse_numbers_line(text, _NUMBER_FIELDS, {"attenuation", "unselected_fidelity"},
                             pattern=r"([a-z ]+): (\S+)", panel="the panel")
    fidelity = out["unselected_fidelity"]
    try:
        out["unselected_fidelity"] = float("nan") if fidelity == NOT_APPLICABLE else float(fidelity)
    except ValueError:
        raise ValueError(f"not a numbers line of the panel: {text!r}") from None
    return out


def face_readout(numbers: dict, region: str, n_vertices: int, units: str) -> str:
    """The numbers line in plain words (Lewis et al. Section 5: the selection held, the rest following the
    sliders), e.g. "brow_middle (2 vertices) held: moved 0.01 cm; the rest follows the sliders 57 %"."""
    moved = f"moved {numbers['selected_motion']:.2g} {units}"
    region = f"{region} ({n_vertices} {'vertex' if n_vertices == 1 else 'vertices'})"
    fidelity = numbers["unselected_fidelity"]
    rest = ("the rest of the face has not been asked to move yet: move a shape slider" if not np.isfinite(fidelity)
            else f"the rest follows the sliders {100 * fidelity:.0f} %")
    if numbers["attenuation"] == "on":
        return f"{region} held: {moved}; {rest}"
    return f"attenuation off: the sliders move the whole face; {region} {moved}"
