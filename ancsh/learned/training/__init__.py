"""Training the networks: losses, training arrays, the training loop, ``torch.compile``, checkpoint choice."""
