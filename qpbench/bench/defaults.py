"""The defaults of the measurement commands (breakdown, head-to-head, sequence, speed), each
written once: the measurements and the command line both read them here. This module imports
nothing, so the command line can read it without loading the measurements."""

# pi-robust's speed target: at least this many times faster than the fastest external pair
# (the main table, each head-to-head set, sequence mode)
TARGET_SPEEDUP = 3.0

# timed repeats of one solve, the fastest kept (sequence, speed)
REPEATS = 5

# head-to-head: timed repeats per solve. The solves here take tens of microseconds to
# milliseconds. With the fastest of 5, a set's speedup still moved by a fifth between passes,
# because bursts on a shared host last longer than 5 such solves. 20 repeats narrowed it, and
# the repeat budget caps the slow solves.
HEAD_TO_HEAD_REPEATS = 20
HEAD_TO_HEAD_PASSES = 3  # whole-set passes, one after another
# head-to-head: timed calls per solve with the CPU caches flushed before each (the cold
# variant, beside the interleaved figure); each flush writes tens of MiB, so fewer than the
# interleaved repeats
HEAD_TO_HEAD_COLD_REPEATS = 3
# head-to-head: problems whose solves are timed together, interleaved (docs/design.md
# section 7); the pairs far slower than the fastest leave a set after each such batch
HEAD_TO_HEAD_BATCH_PROBLEMS = 4
HEAD_TO_HEAD_CANDIDATES = 6  # the fastest external impact pairs compared
# head-to-head: an external pair whose times on a set's problems so far, summed, are more than
# this many times the fastest external pair's there is measured no further on that set. It cannot
# be the fastest, and measuring it in full was most of the benchmark's time: daqp's dense
# factorizations take 30-60 s a solve on the 4,000-ball packings, where piqp takes 4 ms.
HEAD_TO_HEAD_OUT_OF_RUNNING = 30.0
# head-to-head: an external pair's solve whose untimed warm-up took longer than this is timed
# no further (its warm-up's time stands for it), and the pair leaves the set once another pair
# has solved the set's problems within it; the main benchmark's time limit (`make bench`'s
# BENCH_TIMEOUT). A dense factorization takes 12-20 s a solve on a pile of 1,000 circles.
HEAD_TO_HEAD_SOLVE_CAP_S = 10.0

SEQUENCE_STEPS = 30  # impact steps replayed per scene
SEQUENCE_PASSES = 3  # replays of every scene, one after another (as head-to-head's passes)
SEQUENCE_ACCURACY = 1e-8
# sequence: an external pair whose solves on a scene so far, summed, take more than this many
# times those of the fastest warm-startable external pair stops there (as the head-to-head's
# HEAD_TO_HEAD_OUT_OF_RUNNING)
SEQUENCE_OUT_OF_RUNNING = 30.0

SPEED_SIZES = (1000, 4000)  # balls of the box packings

# breakdown: rounds, each timing every part of one problem once (the fastest round of each part
# kept). With 5, a burst of load on the host could double a whole row between two runs.
BREAKDOWN_REPEATS = 20

# sim-precision: scenes (frictionless and frictional, circles, boxes and portals, most with
# SCISim's own final state after SIM_PRECISION_STEPS steps), solver names (pi-robust, the
# fastest external pairs of the main table, Lemke on the lcp form, a first-order method, and
# nsgs, which runs the frictional scenes only) and levels
_FIDELITY = "problems/scisim_fidelity/scenes/"
_SLOPES = _FIDELITY + "ball2d/tests_friction/ball_plane/mu_0p5/"
_ST_SLOPES = _FIDELITY + "ball2d/tests_st/ball_plane/mu_0p5/"
_BOXES = _FIDELITY + "rigidbody2d/tests_serialization/boxes/"
SIM_PRECISION_SCENES = (
    _FIDELITY + "ball2d/examples_gr/butterfly.xml",
    _FIDELITY + "ball2d/examples_gr/nine_ball_break_symmetric.xml",
    _FIDELITY + "ball2d/examples_gr/pool_break_standard.xml",
    _FIDELITY + "ball2d/examples_gr/pool_break_ten_deep.xml",
    _FIDELITY + "ball2d/tests_ccd/ball_ball_ccd_01.xml",
    _FIDELITY + "rigidbody2d/tests_serialization/fixed_body_4.xml",
    _FIDELITY + "rigidbody2d/box_circle/box_circle_1.xml",
    _BOXES + "box_plane_03.xml",
    "problems/scenes/ura/K4.xml",
    "problems/scenes/ura/grid5_itr_0.xml",
    "problems/scenes/ura/10_balls_in_box.xml",
    "problems/scenes/piles/circle_pile_30.xml",
    _SLOPES + "slope_test_posx/ball_slide_above_threshold_10_degree.xml",
    _SLOPES + "slope_test_posx/ball_slide_at_threshold.xml",
    _SLOPES + "slope_test_negx/ball_slide_below_threshold_05_degree.xml",
    _ST_SLOPES + "slope_test_posx/ball_slide_above_threshold_05_degree.xml",
    _ST_SLOPES + "slope_test_negx/ball_slide_below_threshold_20_degree.xml",
    _FIDELITY + "ball2d/tests_serialization/drift_safe_symmetric_break.xml",
    _FIDELITY + "rigidbody2d/tests_serialization/drift_safe_balls_on_planes_01.xml",
    _BOXES + "box_slide_above_threshold.xml",
    _BOXES + "box_slide_below_threshold.xml",
    _BOXES + "box_slide_flat_plane.xml",
    _FIDELITY + "ball2d/lees_edwards/portal_lots_of_collisions.xml",
    _FIDELITY + "rigidbody2d/tests_serialization/portal_lots_of_collisions.xml",
)
SIM_PRECISION_SOLVERS = ("pi-robust", "daqp/dual", "quadprog/primal", "piqp/dual",
                         "clarabel/dual", "osqp/dual", "lemke/lcp", "apgd", "nsgs")
SIM_PRECISION_ACCURACY = (1e-2, 1e-4, 1e-6, 1e-8)
SIM_PRECISION_STEPS = 50  # SCISim's records hold the state after 1, 10 or 50 steps
