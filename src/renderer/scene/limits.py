"""The bounds the scene loader holds a scene's values to: the float32 range of Embree, Mitsuba
and the images, the work one load may take, and the scene sizes the renderer is checked for."""

# Mie tables: the largest relative index of refraction, the largest droplet's size parameter,
# and its product with the table's resolution (a few seconds of work at most).
MAX_MIE_IOR = 10.0
MAX_MIE_SIZE = 2100
MAX_MIE_WORK = 4.2e6
# Bounces a path may make before Russian roulette or max_depth can end it.
MAX_UNROULETTED_DEPTH = 10_000
# Bounds that keep every value representable in the float32 of Embree and of the images.
MAX_LIGHT = 1e30  # emitted radiance, intensity, irradiance
# A direction or axis shorter than this cannot be normalised: its squared length underflows.
MIN_LENGTH = 1e-100
MAX_COORDINATE = 1e15  # |vertex coordinate| (float32 spacing there is ~1e8: far beyond any scene)
# The size of the shapes' bounding box. cbox-fog scaled whole (sigma_t inversely) gave every
# method the same image from a size of 1e-8 to 3.5e12, and wrong ones at 3.5e-9 (pt 12 %
# dark, pm 2x, ppb 3x too bright) and at 3.5e13: the range kept leaves a margin of 10x below.
MIN_SCENE_SIZE, MAX_SCENE_SIZE = 1e-7, 1e12
MAX_EXTINCTION = 1e30  # sigma_t x scale (x the densest voxel): Mitsuba multiplies in float32
# A voxel value: float32 with headroom (the majorant grid widens its bounds by a relative
# margin; at the float32 maximum that overflowed to infinity and tracking never advanced).
MAX_DENSITY = 1e30
# Optical depth across one voxel of a grid (its longest edge, at the densest voxel). Tracking
# pays ~1 lookup per unit of majorant optical depth, and past ~1e14 per unit length a step
# rounds to nothing and a path can collide at one point forever. exp(-1e4) is opaque already;
# the shipped grids stay below 1.
MAX_VOXEL_DEPTH = 1e4
MAX_NOISE_FREQUENCY = 1e6
MAX_FILM_SIDE = 16384
