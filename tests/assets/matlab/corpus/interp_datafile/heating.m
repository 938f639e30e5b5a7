% A room heated by a measured power, u(t) read from a data file
data = load('power.txt');     % two columns: time (h), power (kW)
tdata = data(:,1);
pdata = data(:,2);
C = 2.5;  % kWh/K
k = 0.4;  % kW/K
Tout = 5;
[t, T] = ode45(@(t, T) (interp1(tdata, pdata, t) - k*(T - Tout))/C, [0 12], 15);
plot(t, T)
