"""Scene assembly: the particle store, the collider table, motion, and the Scene itself."""
