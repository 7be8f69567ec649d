"""The action servers (MoveArm, PickPlace, Walk, NavigateToPose, reset pose) and their goal protocol with /sim."""
