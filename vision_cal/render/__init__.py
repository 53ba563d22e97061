"""The synthetic world: a robot with hidden effects draws on a sheet; pyrender photographs it."""
