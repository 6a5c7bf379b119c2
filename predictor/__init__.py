"""Where a capsule will land and how sure we are: weather, terrain, descent physics, uncertainty."""
