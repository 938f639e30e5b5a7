function dy = sdof_rhs(t,y)
global m k
dy = [-k/m*y(2); y(1)];
