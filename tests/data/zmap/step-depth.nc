%
O0431 (seed 001 4.3: depth of cut 0.1 -> 0.7 mm in 5 steps)
N10 G21 G90 G17
N20 S2000 M3
N30 G0 X-20. Y30. Z5.
N40 G1 Z-0.7 F1000
N50 G1 X215. (across the steps)
N60 G0 Z50.
N70 M30
%
