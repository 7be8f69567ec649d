"""The /sim node and its parts: stepping, publishing, the simulation standard, the skills in the loop."""
