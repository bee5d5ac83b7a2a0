"""Style: adversarial motion priors (AMP) — features, discriminator, vec-env wrappers."""
