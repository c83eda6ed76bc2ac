"""Robot models shipped with armstereo: UR URDFs generated from DH tables, and camera mounts.

Kept as a package so the files are found the same way in a checkout and in an installed wheel.
"""

from pathlib import Path

MODELS_DIR = Path(__file__).resolve().parent
MOUNTS_DIR = MODELS_DIR / "mounts"
