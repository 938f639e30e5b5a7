% run the ODE file the MATLAB 5 way: its 'init' flag gives tspan and y0
[t,y] = ode23('vdp5');
plot(t,y(:,1))
