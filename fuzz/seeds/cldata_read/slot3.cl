# 3-axis CL data written for the stlverify tests: a ball end mill
# (ball:2) in two parallel raster passes 0.8 mm apart, 0.3 mm deep, on a
# 10 x 6 x 3 mm stock from (0,0,-3).
x y z
1 2 -0.3
9 2 -0.3
9 2.8 -0.3
1 2.8 -0.3
