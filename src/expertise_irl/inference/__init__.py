"""Inference methods: the discrete-set belief (Eq. 13) and hypothesis-set conditions."""
