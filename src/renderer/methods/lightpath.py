"""What the methods that trace light paths (lt, pm, sppm, ppb, bdpt) check of a scene first
(the native tracer is ``cpp/subpaths.h``; its header documents the records and their units):
that each light's paths can start in one medium (the medium each light emits into is the
scene's, renderer.engine), and that no phase function is too peaked for the methods that
evaluate it where light and camera paths meet.
"""

from __future__ import annotations

import sys

from ..engine import NativeScene
from ..errors import PgiError
from ..scene.model import Scene


def check_emission_media(native: NativeScene) -> None:
    """Refuse an emitter that a boundary of a medium cuts (light paths start in one medium per
    triangle, and would start some of its light in the wrong one); warn, one line each, of
    lights that state a medium where their walk from the camera ends in another."""
    split = native.emission.split_emitters
    if split:
        raise PgiError(
            f"{split[0].describe()}, but light paths start in one medium per triangle: split "
            "the emitter where the boundary crosses it (pt and mitsuba render it as it is)"
        )
    for line in native.emission.stated_elsewhere:
        print(f"pgi: warning: {line}", file=sys.stderr)


# HG media at least this peaked defeat the light-side estimators (docs/media.md): measured on
# cbox-fog, 10 s runs of lt, pm, sppm and ppb were 50 % low to 22 % high at g = 0.999, and
# about 57 % dark at 0.9999 however long they ran.
PEAKED_HG_G = 0.999


def warn_about_peaked_phase_functions(scene: Scene) -> None:
    """A warning on stderr per medium whose HG phase function is too peaked for methods that
    evaluate it where light and camera paths meet (pt samples it instead)."""
    for name, m in scene.media.items():
        if m.phase.type == "hg" and abs(m.phase.g) >= PEAKED_HG_G:
            print(
                f"pgi: warning: {scene.path}: media.{name}.phase.g = {m.phase.g:g}: lt, pm, sppm "
                "and ppb evaluate the phase function where light and camera paths meet, and a "
                "peak this narrow leaves a few rare, huge samples: expect an image far too dark, "
                "with fireflies, that converges very slowly (pt samples the phase function and "
                "stays right)",
                file=sys.stderr,
            )
