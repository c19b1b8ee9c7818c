"""Studies over the bench: the reproduction of thesis chapter 5, side by side."""
