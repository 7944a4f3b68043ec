"""One file per recipe: `RECIPE = Recipe(...)` (training/recipe.py). `python -m training recipe --list`."""
