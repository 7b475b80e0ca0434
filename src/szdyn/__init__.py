"""szdyn: dynamics of the Spiral Zipper friction-driven prismatic actuator."""
