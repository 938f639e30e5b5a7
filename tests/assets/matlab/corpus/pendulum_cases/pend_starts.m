f = @(x,y) [y(2), - sin(y(1))]';
Time = [0, 30];
[A,T] = ode45(f, Time, [0, 0.5]);
figure
plot(A, T(:,1), 'r'), grid on
figure
[A,T] = ode45(f, Time, [pi/4, 0]);
plot(A, T(:,1), 'b'), grid on
figure
[A,T] = ode45(f, Time, [pi/4, 0.5]);
plot(A, T(:,1), 'black'), grid on
