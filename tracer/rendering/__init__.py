"""Rendering a scene: the models compiled into Warp structs, progressive passes on the CPU's cores (or a
GPU), one pixel's ray tree, the film's files, and the cost estimate the service queues by."""
