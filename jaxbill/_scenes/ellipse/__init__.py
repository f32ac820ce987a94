"""The stick in an ellipse and its sections."""
