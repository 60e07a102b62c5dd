"""raindrop_tools: training, ONNX export, reference pipeline and evaluation for raindrop
(Hao et al., "Learning From Synthetic Photorealistic Raindrop for Single Image Raindrop
Removal", ICCV-W 2019).

Modules that need torch: networks, flops, losses, train, export (and morphology.Dilation).
Everything else imports without it: config, data, edge, imageio, metrics, reference,
evaluate, contract.
"""

__version__ = "0.1.0"
