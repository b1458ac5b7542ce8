# raycaster transfer function (volumes/scenes/shapes-windows.toml)
domain 60 255
point 0 0 0 0 0
point 0.35 1 0.5 0.2 0
point 0.5 1 0.6 0.3 0.4
point 1 1 1 0.9 0.9
