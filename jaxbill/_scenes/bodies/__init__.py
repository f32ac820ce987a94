"""The bodies: rigid planar bodies and the way each touches a wall."""
