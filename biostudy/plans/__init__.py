"""Stage 2, plans: many cases of one scene (studies, sampling designs, refinements, stability catalogues), validated."""
