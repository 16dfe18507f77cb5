"""LightningModules: odometry (velocity regression); classification and noisy-label training join here."""
