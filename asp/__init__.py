"""ASP encodings (.lp files) shipped as package data; found via importlib.resources."""
