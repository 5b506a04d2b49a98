"""The patch construction at extraordinary points ([FSLYJ] secs. 3-4.2), in the paper's order:
``extraction`` (bicubic Bézier extraction with auxiliary anchors, sec. 3.2),
``angle_configuration`` (angles, lengths and connecting functions, sec. 3.3),
``g1_constraints`` (the G1 equations across a spoke, sec. 3.3-3.4), ``g1_patches`` (the
bi-quintic patches as row mixings, sec. 3.4), ``cluster_fairing`` (our joint solve for EPs
joined by spokes), ``auxiliary_points`` and ``anchor_fairing`` (the anchors, sec. 3.5)."""
