"""Many cases of one scene (studies, sampling designs, refinements, stability catalogues), validated."""
