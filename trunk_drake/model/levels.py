"""The five lumbar levels, caudal to cranial: the one definition every module uses."""

LEVELS = ("L5_S1", "L4_L5", "L3_L4", "L2_L3", "L1_L2")
#: the child vertebra of each level as MyoTorso and Lumbar_C_210 name it (an .osim mapping may name others)
LEVEL_BODIES = ("lumbar5", "lumbar4", "lumbar3", "lumbar2", "lumbar1")
#: their flexion-extension coordinates (flexion +): the order of per-level arrays such as
#: TrunkOptions.stiffness, and the level angles of measured trials
LUMBAR_LEVELS = tuple(f"{level}_FE" for level in LEVELS)
