# 5-axis CL data written for the stlverify tests: tool tip, then a second
# point on the tool axis; the axis tilts from vertical to 20 degrees about
# X along a 6 mm pass.
x y z x1 y1 z1
2 3 -0.5 2 3 9.5
5 3 -0.6 5 4.71 9.25
8 3 -0.7 8 6.42 8.70
