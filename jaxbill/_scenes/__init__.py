"""The scenes, each in its own folder, and the protocols through which the engine and the analyses ask them."""
