"""Write the paper's beam stack (the shipped default scene) as Gmsh line meshes.

One physical line group per segment, named like the segment; points at (x, y_c, z_c).
Run from anywhere:  python meshes/generate.py   (writes paper_stack_<elements>.msh here)
"""

from pathlib import Path

from nsfem.mesh import generate, write
from nsfem.scene import load_scene

LEVELS = (20, 40, 80)

if __name__ == "__main__":
    stack = load_scene(None).stack
    here = Path(__file__).resolve().parent
    for n in LEVELS:
        path = write(here / f"paper_stack_{n}.msh", stack, generate(stack, n))
        print(path)
