"""Small types every package shares: the verdict, the JSON encoding, file names, parameter sets and the thesis-vs-project row."""
