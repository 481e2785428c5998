"""The feature matrix's reference images, installed with the harness as package data
(``wrt_harness.reference_images``; see README.md here)."""
