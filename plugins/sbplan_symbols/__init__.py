"""Built-in candidate reference symbols (parametric polygons), registered through the sbplan entry-point group."""
