"""The shared bottom layer: model wrapper, argument checks, feature evaluation.

Nothing here imports from the rest of the package; every other subpackage
may import from here.
"""
