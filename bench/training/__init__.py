"""Training the PoI detector and HardNet on synthetic renders (torch extra): data, objectives,
evaluation and the resumable ``drkfs train`` run."""
