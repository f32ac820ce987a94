"""The stick in a circle (rotor, lens, circle billiard) and its sections."""
