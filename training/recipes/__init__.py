"""One file per recipe: `RECIPE = Recipe(...)` (training/recipes/base.py). `python -m training recipe --list`."""
