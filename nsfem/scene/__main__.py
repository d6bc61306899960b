"""``python -m nsfem.scene > docs/scene.md``."""

from .reference import scene_reference


if __name__ == "__main__":  # pragma: no cover
    print(scene_reference())
