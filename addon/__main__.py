"""`python -m addon scene.blend --out solved.blend [--preset draft] [--render solved.png]`, run
from the repository root: the headless solve of cli.py for users of the `bpy` module."""
import sys

from .cli import main

sys.exit(main())
