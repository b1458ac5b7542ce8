# raycaster transfer function (volumes/scenes/shapes-windows.toml)
domain 0 120
point 0 0 0 0 0
point 0.3 0.2 0.4 1 0
point 0.6 0.3 0.6 1 0.08
point 1 0.8 0.9 1 0.2
