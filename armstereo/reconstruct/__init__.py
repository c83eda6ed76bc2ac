"""Reconstruction, in the order the data flows: :mod:`.rectify` (Fusiello from poses),
:mod:`.window` (which depths to match), :mod:`.stereo` (Birchfield-Tomasi in :mod:`.birchfield`,
or SGBM), :mod:`.triangulate` (disparity -> base-frame points); :mod:`.views` chains them for
two images with poses (the public :func:`reconstruct_views`), :mod:`.pipeline` for a recorded
pair, and :mod:`.outputs` writes the products."""
