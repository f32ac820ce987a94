"""Independent checks of the collision map: the diffrax-integrated flights."""
