"""Exporters of a design: URDF, MJCF, STL, bill of materials, design record."""
