%
O0100 (BAD PROGRAM TEST)
G21 G90 G17 G94
G0 X0 Y0 Z5
G1 X1 Ä F10 (ä in a comment is fine)
M30
%
