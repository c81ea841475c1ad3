"""jampacked.export: packings to watertight, printable meshes."""
