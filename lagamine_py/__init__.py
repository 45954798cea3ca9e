"""lagamine_py: 2D and axisymmetric large-strain finite elements with the frictional contact
model of Godinas, Charlier & Cescotto, driven by keyword ``.dat`` decks."""
__version__ = "0.1.0"
