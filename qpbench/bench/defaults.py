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
HEAD_TO_HEAD_CANDIDATES = 6  # the fastest external impact pairs compared
# head-to-head: an external pair whose times on a set's problems so far, summed, are more than
# this many times the fastest external pair's there is measured no further on that set. It cannot
# be the fastest, and measuring it in full was most of the benchmark's time: daqp's dense
# factorizations take 30-60 s a solve on the 4,000-ball packings, where piqp takes 4 ms.
HEAD_TO_HEAD_OUT_OF_RUNNING = 30.0

SEQUENCE_STEPS = 30  # impact steps replayed per scene
SEQUENCE_PASSES = 3  # replays of every scene, one after another (as head-to-head's passes)
SEQUENCE_ACCURACY = 1e-8

SPEED_SIZES = (1000, 4000)  # balls of the box packings

# breakdown: rounds, each timing every part of one problem once (the fastest round of each part
# kept). With 5, a burst of load on the host could double a whole row between two runs.
BREAKDOWN_REPEATS = 20
