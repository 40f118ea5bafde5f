"""Pictures of a scene (filled below)."""
