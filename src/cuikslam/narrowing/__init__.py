"""narrowing."""
