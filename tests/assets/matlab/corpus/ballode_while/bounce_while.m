% A ball dropped from 5 m, restarted at each bounce until the final time
g = 9.81;
e = 0.7;               % restitution
tstart = 0; tfinal = 4.5;
y0 = [5 0];
opts = odeset('Events', @ground, 'RelTol', 1e-8, 'AbsTol', 1e-10);
T = []; Y = [];
while tstart < tfinal
    [t, y, te, ye] = ode45(@(t, y) [y(2); -g], [tstart tfinal], y0, opts);
    T = [T; t]; Y = [Y; y];
    tstart = t(end);
    y0 = [0, -e*ye(2)];
end
plot(T, Y(:,1))

function [value, isterminal, direction] = ground(t, y)
value = y(1);
isterminal = 1;
direction = -1;
end
