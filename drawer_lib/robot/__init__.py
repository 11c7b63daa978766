"""The robot stage: a Franka Panda opens and closes the twin's parts; demonstrations, transfer to the ground truth."""
