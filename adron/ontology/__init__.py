"""The ADROn ontology, as SUO-KIF files shipped with parmor."""
