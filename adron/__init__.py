"""ADROn: the SUO-KIF reader, the ontology files and the KIF -> ASP translation."""
