"""The method ids pgi knows: the methods it implements and the study's methods still to come.

Plain data with no imports, read by the method registry (renderer.methods) and by the scene
loader, which checks a scene's ``expected_winners`` against it: the loader must not import the
registry, whose modules import the scene package.
"""

# id -> (module in renderer.methods, class name, one-line description), in the order
# `pgi methods` lists them.
IMPLEMENTED: dict[str, tuple[str, str, str]] = {
    "pt": ("pt", "PathTracing", "volumetric path tracing, next-event estimation and MIS"),
    "lt": ("lt", "LightTracing", "light tracing: light paths connected to the camera"),
    "pm": (
        "pm",
        "PhotonMapping",
        "photon mapping with volume photons and the beam radiance estimate (fixed radius)",
    ),
    "sppm": (
        "sppm",
        "StochasticProgressivePhotonMapping",
        "stochastic progressive photon mapping, surfaces and media (Knaus-Zwicker radii)",
    ),
    "ppb": (
        "ppb",
        "ProgressivePhotonBeams",
        "progressive photon beams (beam x beam 1D) in media, photons on surfaces",
    ),
    "bdpt": (
        "bdpt",
        "BidirectionalPathTracing",
        "bidirectional path tracing in media, every connection strategy, MIS",
    ),
    "vpl": (
        "vpl",
        "VirtualPointLights",
        "virtual point lights (instant radiosity) in media, clamped geometry term",
    ),
    "vsl": (
        "vsl",
        "VirtualSphericalLights",
        "virtual spherical lights in media, radius shrinking progressively",
    ),
    "vrl": (
        "vrl",
        "VirtualRayLights",
        "virtual ray lights: light paths' medium segments gathered along camera rays",
    ),
    "vbl": (
        "vbl",
        "VirtualBeamLights",
        "progressive virtual beam lights: ray lights thickened, radius shrinking",
    ),
    "mitsuba": ("mitsuba", "MitsubaVolpath", "Mitsuba 3 volpath at the same budget"),
}

# Methods that are not the study's: rendered by name (tests, docs), never listed or studied.
EXAMPLES: dict[str, tuple[str, str, str]] = {
    "direct": ("direct", "DirectLighting", "direct lighting at the first surface (an example)"),
}

# Methods of the study's method table (docs/methods.md) that pgi does not implement yet.
# Scenes may name them among the methods expected to win; nothing can render with them.
NOT_YET_IMPLEMENTED: dict[str, str] = {}
