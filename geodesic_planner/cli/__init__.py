"""Console scripts: geodesic-plan, geodesic-compare, geodesic-bag."""
