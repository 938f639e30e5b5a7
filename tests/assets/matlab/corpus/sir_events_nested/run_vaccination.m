% the outbreak until fewer than one person is infected
[t,S,I,R] = vaccination_sir(200, 990, 10, 0, 0.002, 0.3, 0.1);
plot(t, [S I R])
